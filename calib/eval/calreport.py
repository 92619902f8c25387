"""`viewcomp calibrate --report DIR`: the verdict as calibration.json and pictures an operator
reads at a glance.

- ``calibration.json``: the verdict (:mod:`viewcomp.calib.eval.verdict`), its findings with
  their thresholds, and the fits' statistics (``Calibration.info``).
- ``exposure.png``: the white screen at the projector's full output per pixel, as a fraction
  of the camera's range (too dark, clipped, a hot spot, vignetting).
- ``residual.png``: the per-pixel model's error on the real screen's ramp capture (where the
  model does not describe the screen).
- ``gamut.png``: the compensable gamut: per pixel, the brightest white of the white screen
  (as a fraction of its full output) that the real screen can show to a viewer at 90 degrees
  - 1 where the screen can match a white screen, lower where its colour or darkness limits
  what any compensation can show.
- ``reach.png``: the per-pixel reach seen by a viewer at 90 degrees: per projector pixel the
  highest colour (every channel at full drive) and the lowest (the projector's black) it can
  produce on the surface, beside the white screen at full output
  (:mod:`viewcomp.calib.eval.reach_picture`).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from viewcomp.calib.eval.reach_picture import reach_picture
from viewcomp.calib.eval.verdict import Verdict
from viewcomp.calib.fit.calibrate import Calibration
from viewcomp.calib.io.atomic import atomic_dir, atomic_open
from viewcomp.calib.io.imageio import write_png
from viewcomp.calib.model.reference import screen_at, white_response

REPORT_FILES = ("calibration.json", "exposure.png", "residual.png", "gamut.png", "reach.png")
#: The angle (degrees) of the viewer the report's gamut and reach pictures are seen by.
REPORT_ANGLE = 90.0


def reachable_white(cal: Calibration, eye: np.ndarray) -> np.ndarray:
    """(H, W) float32 in 0..1: per pixel the largest k such that k times the white screen's
    full output is shown by the real screen seen from ``eye`` (metres) with a projector drive
    y in [0, 1]^3 (the per-pixel model: M y + A = k t, M and A at the eye, t the white
    screen's full output). 0 where even black is brighter than the target can be."""
    model = cal.pixel.runtime_model()
    h, w = model.shape
    target = white_response(model, np.full((h, w, 3), 255, np.uint8)).astype(np.float64)
    m, a = screen_at(model, np.asarray(eye, np.float64))
    m = np.asarray(m, np.float64)
    u = np.linalg.solve(m, target[..., None])[..., 0]  # y = k u - v
    v = np.linalg.solve(m, np.asarray(a, np.float64)[..., None])[..., 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        lo_c = np.where(u > 0, v / u, (1.0 + v) / u)  # bounds on k from 0 <= k u - v <= 1
        hi_c = np.where(u > 0, (1.0 + v) / u, v / u)
    free = np.abs(u) < 1e-12  # k does not move this channel: it must already be inside
    inside = (v <= 0) & (v >= -1)
    lo_c = np.where(free, np.where(inside, -np.inf, np.inf), lo_c)
    hi_c = np.where(free, np.where(inside, np.inf, -np.inf), hi_c)
    lo, hi = lo_c.max(axis=-1), hi_c.min(axis=-1)
    k = np.where(hi >= np.maximum(lo, 0.0), hi, 0.0)
    return np.clip(k, 0.0, 1.0).astype(np.float32)


def _picture(path: Path, data: np.ndarray, title: str, label: str, vmax: float) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    h, w = data.shape
    fig, ax = plt.subplots(figsize=(7.0, 7.0 * h / w + 0.8))
    im = ax.imshow(data, cmap="viridis", vmin=0.0, vmax=vmax, interpolation="nearest")
    ax.set_title(title, fontsize=10)
    ax.set_xlabel("projector x (px)")
    ax.set_ylabel("projector y (px)")
    fig.colorbar(im, ax=ax, label=label, fraction=0.046, pad=0.04)
    with atomic_open(path) as f:
        fig.savefig(f, format="png", dpi=100, bbox_inches="tight")
    plt.close(fig)


def write_calibration_report(
    out: str | Path, cal: Calibration, verdict: Verdict, maps: dict[str, np.ndarray]
) -> list[Path]:
    """Write :data:`REPORT_FILES` into the folder ``out`` (made or replaced whole, atomically);
    ``maps`` holds ``"ramp_residual"`` (H, W) from ``calibrate(..., maps=...)``."""
    full = cal.pixel.white.W.sum(axis=-1) + cal.pixel.white.A
    eye = cal.eye(REPORT_ANGLE)
    reach = reachable_white(cal, eye)
    summary: dict[str, Any] = {
        "verdict": verdict.to_json(),
        "gamut_at_90": {
            "median": round(float(np.median(reach)), 4),
            "p05": round(float(np.percentile(reach, 5.0)), 4),
        },
        "info": cal.info,
    }
    with atomic_dir(out) as tmp:
        with atomic_open(tmp / "calibration.json") as f:
            f.write((json.dumps(summary, indent=2, default=float) + "\n").encode("utf-8"))
        _picture(
            tmp / "exposure.png",
            full.mean(axis=-1),
            f"exposure: the white screen at full output ({verdict.level} calibration)",
            "fraction of the camera's range",
            max(1.0, float(full.max())),
        )
        resid = maps["ramp_residual"]
        _picture(
            tmp / "residual.png",
            resid,
            "per-pixel model's error on the real screen's ramp capture",
            "relative error",
            max(0.05, float(np.percentile(resid, 99.0))),
        )
        _picture(
            tmp / "gamut.png",
            reach,
            "compensable gamut at 90 degrees: brightest white the screen can show",
            "fraction of the white screen's full output",
            1.0,
        )
        write_png(
            tmp / "reach.png",
            reach_picture(
                cal,
                [(f"seen at {REPORT_ANGLE:.0f} degrees", eye)],
                f"per-pixel reach at {REPORT_ANGLE:.0f} degrees: the highest and lowest colour "
                "each projector pixel can produce on the surface",
            ),
        )
    return [Path(out) / name for name in REPORT_FILES]
