"""The audience protocol (docs/EVALUATION.md, "Audience"): compensation for several viewers
at once, and for a tracked viewer, judged by what each viewer sees.

**Zone.** Viewers spread over a zone of angles (60..120 degrees by default), on the glossy
screens of the sweep with its natural images. Every column is judged at ``judge`` angles
evenly over the zone (13: every 5 degrees over 60..120, twice as dense as the audience's own
7 viewers, so the viewers between them count too), by the mean CIEDE2000 between what a
viewer there sees and the same image on the white screen (T_i of
:mod:`~viewcomp.calib.eval.evaluate`). Columns, all of the per-pixel method:

- ``pixel_90``: compensated for 90 degrees (the calibration camera's view);
- ``pixel_centre``: compensated for the zone's centre angle (for 60..120 that is 90 again);
- ``pixel_audience``: compensated for the zone's audience (``viewcomp render --audience
  A:B``): the least squares over its viewers (docs/MODEL.md section 6);
- ``oracle``: for each viewer, the true model at that viewer's eye inverted exactly (the
  physical limit for a viewer alone; no single image reaches it for all at once).

Per row (screen, image, zone): the mean over the zone and the worst (largest) viewer's dE.

**Walk.** A viewer walks across (the simulated walk of ``viewcomp.rt.track.simtrack``: 1..3 m,
90 +- 40 degrees, 12 s), tracked by the face tracker in the tracking camera's frames. The
walk is scaled about the screen centre so that its mean distance is the world's viewer
distance (the simulated screen is small): every angle under which the viewer sees the screen
is kept, and the tracker's errors scale with the walk. Every ``every``-th frame: dE seen from
the true eye for ``tracked`` (compensated for the tracked eye of ``delay`` frames earlier:
the tracker's filter lag and noise, and the camera-to-player latency), ``exact``
(compensated for the true eye) and ``pixel_90``.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np

from viewcomp.calib.eval.adapted import adapted_delta_e
from viewcomp.calib.eval.evaluate import SWEEP_SCREENS, Progress, World
from viewcomp.calib.eval.metrics import delta_e2000
from viewcomp.calib.eval.testimages import natural_images
from viewcomp.calib.sim.simulator import white_screen
from viewcomp.calib.world.audience import ZONE_VIEWERS, zone
from viewcomp.calib.world.eye import eye_to_polar

ZONES = ((60.0, 120.0), (30.0, 90.0))  # the documented zone (README), and one off-centre
JUDGE_VIEWERS = 13  # angles each zone is judged at
ZONE_KEYS = ("pixel_90", "pixel_centre", "pixel_audience", "oracle")
WALK_KEYS = ("tracked", "exact", "pixel_90")
WALK_SCREEN = "magenta"


def zone_rows(
    world: World,
    zones: Iterable[tuple[float, float]] = ZONES,
    screens: Iterable[str] = SWEEP_SCREENS,
    images: dict[str, np.ndarray] | None = None,
    viewers: int = ZONE_VIEWERS,
    judge: int = JUDGE_VIEWERS,
    progress: Progress | None = None,
) -> list[dict[str, Any]]:
    """One row per (screen, image, zone): dE per column at each judged angle, their mean and
    worst (see the module docstring). ``viewers``: the audience's viewers per zone."""
    h, w = world.shape
    imgs = images if images is not None else natural_images(w, h)
    v = world.sim.rig.viewer
    rows = []
    for name in screens:
        case = world.case(name)
        for iname, image in imgs.items():
            at90, _ = case.pixel.compensate_image(image, world.eye(90.0))
            for lo, hi in zones:
                centre = (lo + hi) / 2.0
                comps = {
                    "pixel_90": at90,
                    "pixel_centre": at90
                    if centre == 90.0
                    else case.pixel.compensate_image(image, world.eye(centre))[0],
                    "pixel_audience": case.pixel.compensate_image(
                        image, zone(lo, hi, viewers, v.distance, v.height or 0.0)
                    )[0],
                }
                angles = np.linspace(lo, hi, judge)
                de: dict[str, list[float]] = {k: [] for k in ZONE_KEYS}
                ade: dict[str, list[float]] = {k: [] for k in ZONE_KEYS}
                for a in angles:
                    eye = world.eye(float(a))
                    t_i = world.sim.observe(white_screen(), image, eye)
                    comps["oracle"] = world.oracle(case.screen, image, eye)
                    for k, img in comps.items():
                        seen = world.sim.observe(case.screen, img, eye)
                        de[k].append(delta_e2000(seen, t_i))
                        ade[k].append(adapted_delta_e(seen, t_i).de)
                rows.append(
                    {
                        "screen": name,
                        "image": iname,
                        "zone": [lo, hi],
                        "angles": [round(float(a), 3) for a in angles],
                        "de": de,
                        "mean": {k: float(np.mean(x)) for k, x in de.items()},
                        "worst": {k: float(np.max(x)) for k, x in de.items()},
                        "adapted_mean": {k: float(np.mean(x)) for k, x in ade.items()},
                    }
                )
            if progress:
                progress(f"audience: {name} screen, image {iname} done")
    return rows


def zone_summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Per zone: the mean over rows of each column's zone mean and zone worst, and the
    issue's criteria counted per row and checked on those means (not asserted)."""
    out: dict[str, Any] = {}
    for key in sorted({tuple(r["zone"]) for r in rows}):
        rs = [r for r in rows if tuple(r["zone"]) == key]
        mean = {k: float(np.mean([r["mean"][k] for r in rs])) for k in ZONE_KEYS}
        worst = {k: float(np.mean([r["worst"][k] for r in rs])) for k in ZONE_KEYS}

        def rows_where(f: Any, rs: list[dict[str, Any]] = rs) -> int:
            return sum(1 for r in rs if f(r))

        out[f"{key[0]:g}:{key[1]:g}"] = {
            "mean": mean,
            "worst": worst,
            # The adapted dE (docs/EVALUATION.md): the mean over rows of each column's zone mean.
            "adapted_mean": {
                k: float(np.mean([r["adapted_mean"][k] for r in rs])) for k in ZONE_KEYS
            },
            "rows": len(rs),
            "rows_audience_mean_lt_90": rows_where(
                lambda r: r["mean"]["pixel_audience"] < r["mean"]["pixel_90"]
            ),
            "rows_audience_mean_lt_centre": rows_where(
                lambda r: r["mean"]["pixel_audience"] < r["mean"]["pixel_centre"]
            ),
            "rows_audience_worst_lt_90": rows_where(
                lambda r: r["worst"]["pixel_audience"] < r["worst"]["pixel_90"]
            ),
            "audience_mean_lt_90_and_centre": mean["pixel_audience"]
            < min(mean["pixel_90"], mean["pixel_centre"]),
            "audience_worst_lt_90": worst["pixel_audience"] < worst["pixel_90"],
        }
    return out


def walk_rows(
    world: World,
    times: np.ndarray,
    truth: np.ndarray,
    tracked: np.ndarray,
    delay: int = 3,
    every: int = 6,
    screen: str = WALK_SCREEN,
    image: str = "astronaut",
    progress: Progress | None = None,
) -> dict[str, Any]:
    """dE over time for a tracked walk (see the module docstring).

    Args:
        world: the evaluation world.
        times, truth, tracked: (n,), (n, 3), (n, 3): the walk's times (s), true and tracked
            eyes (metres, the tracking camera's world).
        delay: frames between a camera frame and the first player frame that uses its eye
            (3 at 30 fps: 100 ms, the latency budget of a tracked viewer).
        every: judge every ``every``-th frame.
        screen, image: the screen (glossy) and the natural image.

    Returns:
        ``scale`` (the walk's scale), ``rows`` (t, true and tracked angle, the eye error in
        metres before scaling, dE per column) and ``summary`` (mean and 95th percentile per
        column, and the mean of tracked - exact).
    """
    h, w = world.shape
    img = natural_images(w, h)[image]
    case = world.case(screen)
    scale = float(world.sim.rig.viewer.distance / np.mean(np.linalg.norm(truth, axis=1)))
    at90, _ = case.pixel.compensate_image(img, world.eye(90.0))
    rows: list[dict[str, Any]] = []
    for i in range(0, len(times), max(1, int(every))):
        late = tracked[max(0, i - int(delay))]
        eye, seen = truth[i] * scale, late * scale
        t_i = world.sim.observe(white_screen(), img, eye)
        comps = {
            "tracked": case.pixel.compensate_image(img, seen)[0],
            "exact": case.pixel.compensate_image(img, eye)[0],
            "pixel_90": at90,
        }
        de = {k: delta_e2000(world.sim.observe(case.screen, c, eye), t_i) for k, c in comps.items()}
        rows.append(
            {
                "t": round(float(times[i]), 4),
                "angle": round(eye_to_polar(eye)[0], 3),
                "tracked_angle": round(eye_to_polar(seen)[0], 3),
                "eye_error_m": round(
                    float(np.linalg.norm(tracked[max(0, i - delay)] - truth[i])), 4
                ),
                "de": de,
            }
        )
        if progress and len(rows) % 10 == 0:
            progress(f"audience: walk, {len(rows)} frames judged")
    de_all = {k: np.array([r["de"][k] for r in rows]) for k in WALK_KEYS}
    summary = {
        "mean": {k: float(v.mean()) for k, v in de_all.items()},
        "p95": {k: float(np.percentile(v, 95)) for k, v in de_all.items()},
        "tracked_minus_exact_mean": float(np.mean(de_all["tracked"] - de_all["exact"])),
        "frames_judged": len(rows),
        "delay_frames": int(delay),
        "screen": screen,
        "image": image,
    }
    return {"scale": scale, "rows": rows, "summary": summary}
