"""The calibration bundle's layout: which arrays and which meta.json entries hold each part of
a calibration (the rig, both methods' fits, the per-pixel maps), written and read back.

The container (a zip of .npy arrays and meta.json, checked member by member, atomic) is
:mod:`viewcomp.calib.io.bundle`'s; the per-pixel maps are stored compact
(:mod:`viewcomp.calib.io.compact`: error-bounded integers); the geometry is not stored at all:
the rig in meta.json gives it back exactly (``ScreenGeometry.from_rig``), checked against the
device positions listed beside it.
"""

from __future__ import annotations

import itertools
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from viewcomp.calib.errors import BundleError
from viewcomp.calib.fit.paper import CHANNEL_PATTERNS, PaperCalibration, PhongFit
from viewcomp.calib.fit.pixel import LobeFit, PixelCalibration, ScreenModel
from viewcomp.calib.io.bundle import CALIBRATION_ARRAYS, load_bundle, save_bundle
from viewcomp.calib.io.compact import decode_screen, encode_screen
from viewcomp.calib.model.lobe import LOBE_N, LOBE_PARAMS
from viewcomp.calib.world.geometry import ScreenGeometry
from viewcomp.calib.world.rig import Rig, rig_from_dict, rig_to_toml

Parts = tuple[Rig, PaperCalibration | None, PixelCalibration, dict[str, Any]]


def save_calibration(
    path: str | Path,
    rig: Rig,
    paper: PaperCalibration | None,
    pixel: PixelCalibration,
    info: dict[str, Any],
) -> None:
    """Write a calibration's parts as a bundle, atomically at exactly ``path``."""
    p, x = paper, pixel
    g = x.geometry
    lobe = x.lobe
    # The per-pixel maps compact (viewcomp.calib.io.compact: error-bounded integers);
    # the geometry not at all: the rig in meta gives it back exactly (from_rig).
    arrays = {
        "pixel.f_lut": x.f_lut,
        "pixel.lobe": lobe.table,
        "pixel.baseline": lobe.baseline,
        "pixel.black_share": x.black_share,
    }
    meta: dict[str, Any] = {
        "rig": rig_to_toml(rig),
        "methods": ["pixel"] if paper is None else ["pixel", "paper"],
        "geometry": {"projector": g.projector.tolist(), "camera": g.camera.tolist()},
        "pixel_fit": {
            "lobe_param": lobe.param,
            "t_seen": list(lobe.t_seen),
            "rms": lobe.rms.tolist(),
            "rms_other": lobe.rms_other.tolist(),
            "rms_phong": finite_list(lobe.rms_phong),
            "rms_power_law": finite_list(lobe.rms_power_law),
            "peak": lobe.peak.tolist(),
            "samples": lobe.samples,
            "masked": lobe.masked,
            "message": lobe.message,
            "response_rms": x.response_rms,
            "ambient_measured": x.screen.ambient_measured,
        },
        "info": info,
    }
    if p is not None:
        assert p.stat_mask is not None  # calibrate_paper sets it
        arrays |= {
            "paper.n": p.n,
            "paper.means_c": np.stack([p.means_c[k] for k in (*CHANNEL_PATTERNS, "gray")]),
            "paper.ramp_cols_c": p.ramp_cols_c,
            "paper.w_tilde_w": p.w_tilde_w,
            "paper.rho_w": p.rho_w,
            "paper.ksis": p.fit.ksis,
            "paper.gamma": p.fit.gamma,
            "paper.stat_mask": p.stat_mask.astype(np.uint8),
        }
        meta["paper_fit"] = {
            "mode": p.fit.mode,
            "samples": p.fit.samples,
            "rms_log": p.fit.rms.tolist(),
            "r2": p.fit.r2.tolist(),
        }
    # The maps last, encoded one array at a time as the bundle is written.
    pairs = itertools.chain(
        arrays.items(),
        encode_screen("w", x.white.W, x.white.A),
        encode_screen("c", x.screen.W, x.screen.A),
    )
    save_bundle(path, pairs, meta)


def load_calibration(path: str | Path) -> Parts:
    """The parts (rig, paper or None, pixel, info) of a bundle written by
    :func:`save_calibration`.

    Raises:
        BundleError: unreadable, corrupt, of another schema, or missing a part.
    """
    arrays, meta = load_bundle(path, CALIBRATION_ARRAYS)
    try:
        rig = rig_from_dict(_toml_loads(meta["rig"]), source=f"{path} (rig)")
        # The geometry calibrate used, computed again from the same rig (exactly).
        # The two screens' maps decode on a second thread meanwhile (numpy's work there
        # releases the GIL): the load is on the player's start-up path.
        with ThreadPoolExecutor(max_workers=2) as pool:
            white = pool.submit(decode_screen, arrays, "w")
            screen = pool.submit(decode_screen, arrays, "c")
            g = ScreenGeometry.from_rig(rig)
            (white_w, white_a), (screen_w, screen_a) = white.result(), screen.result()
        for device in ("projector", "camera"):
            listed = np.asarray(meta["geometry"][device], np.float64)
            if listed.shape != (3,) or not np.array_equal(listed, getattr(g, device)):
                raise ValueError(f"the {device} is at {listed}, its rig says otherwise")
        for name, m in (("Ww", white_w), ("Aw", white_a), ("Wc", screen_w), ("Ac", screen_a)):
            if m.shape[:2] != g.pos.shape[:2] or not np.all(np.isfinite(m)):
                raise ValueError(f"pixel.{name} decodes to {m.shape} or to non-finite values")
        paper = _paper_from(arrays, meta, g) if "paper" in meta["methods"] else None
        xf = meta["pixel_fit"]
        lobe = _lobe_from(arrays, xf)
        if lobe.param not in LOBE_PARAMS or lobe.table.shape != (LOBE_N, 3):
            raise ValueError(f"lobe {lobe.param!r} of shape {lobe.table.shape}")
        measured = bool(xf["ambient_measured"])
        pixel = PixelCalibration(
            geometry=g,
            f_lut=arrays["pixel.f_lut"],
            white=ScreenModel(white_w, white_a, measured),
            screen=ScreenModel(screen_w, screen_a, measured),
            lobe=lobe,
            response_rms=float(xf["response_rms"]),
            black_share=arrays["pixel.black_share"],
        )
    except (KeyError, TypeError, ValueError) as e:
        raise BundleError(
            f"{path}: the bundle is incomplete or inconsistent ({e!r}): recalibrate with "
            "`viewcomp calibrate CAPTURE_DIR -o CALIB`"
        ) from e
    return rig, paper, pixel, dict(meta.get("info", {}))


def _paper_from(
    arrays: dict[str, np.ndarray], meta: dict[str, Any], g: ScreenGeometry
) -> PaperCalibration:
    """The paper's method as stored (KeyError, TypeError, ValueError: a part missing)."""
    pf = meta["paper_fit"]
    fit = PhongFit(
        ksis=arrays["paper.ksis"],
        gamma=arrays["paper.gamma"],
        rms=np.asarray(pf["rms_log"]),
        r2=np.asarray(pf["r2"]),
        samples=int(pf["samples"]),
        mode=str(pf["mode"]),
    )
    means = arrays["paper.means_c"]
    return PaperCalibration(
        geometry=g,
        n=arrays["paper.n"],
        fit=fit,
        means_c={k: means[i] for i, k in enumerate((*CHANNEL_PATTERNS, "gray"))},
        ramp_cols_c=arrays["paper.ramp_cols_c"],
        w_tilde_w=arrays["paper.w_tilde_w"],
        rho_w=arrays["paper.rho_w"],
        rv90=g.rv(g.camera),
        stat_mask=arrays["paper.stat_mask"].astype(bool),
    )


def _lobe_from(arrays: dict[str, np.ndarray], xf: dict[str, Any]) -> LobeFit:
    """The per-pixel method's lobe fit as stored (KeyError, ...: a part missing)."""
    return LobeFit(
        param=str(xf["lobe_param"]),
        table=arrays["pixel.lobe"],
        baseline=arrays["pixel.baseline"],
        t_seen=(float(xf["t_seen"][0]), float(xf["t_seen"][1])),
        rms=np.asarray(xf["rms"], np.float64),
        rms_other=np.asarray(xf["rms_other"], np.float64),
        rms_phong=np.asarray(xf["rms_phong"], np.float64),
        rms_power_law=np.asarray(xf["rms_power_law"], np.float64),
        peak=np.asarray(xf["peak"], np.float64),
        samples=int(xf["samples"]),
        masked=int(xf["masked"]),
        message=str(xf["message"]),
    )


def finite_list(a: np.ndarray) -> list[float | None]:
    """JSON-safe floats: NaN (a comparison fit that could not run) as None (null)."""
    return [float(v) if np.isfinite(v) else None for v in np.asarray(a, np.float64)]


def _toml_loads(text: str) -> dict[str, Any]:
    import tomllib

    return tomllib.loads(text)
