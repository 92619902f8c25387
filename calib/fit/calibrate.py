"""From a capture set to a calibration bundle, and back: both methods in one file.

``calibrate(capture_set)`` runs the paper's method and the per-pixel method on the same
linearised captures and checks them first (saturation, darkness, size); ``Calibration``
saves to and loads from the bundle (``viewcomp.calib.io.bundle``: a zip of .npy arrays and
JSON, no pickle, atomic) and compensates images on the CPU (the numpy reference).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from viewcomp.calib.errors import FitError
from viewcomp.calib.fit.paper import CHANNEL_PATTERNS, PaperCalibration, PhongFit, calibrate_paper
from viewcomp.calib.fit.pixel import (
    DEFAULT_SMOOTH_PX,
    LobeFit,
    PixelCalibration,
    ScreenModel,
    calibrate_pixel,
)
from viewcomp.calib.io.bundle import CALIBRATION_ARRAYS, BundleError, load_bundle, save_bundle
from viewcomp.calib.io.captureset import REQUIRED, CaptureSet
from viewcomp.calib.io.checks import check_captures
from viewcomp.calib.world.eye import EyeError, check_angle, check_eye
from viewcomp.calib.world.geometry import ScreenGeometry
from viewcomp.calib.world.rig import Rig, rig_from_dict, rig_to_toml


@dataclass
class Calibration:
    """Both methods' calibrations for one rig, plus what the fits said."""

    rig: Rig
    paper: PaperCalibration
    pixel: PixelCalibration
    info: dict[str, Any]

    @property
    def shape(self) -> tuple[int, int]:
        """(H, W) of the projector grid."""
        return self.paper.rv90.shape

    def eye(self, angle: float | None = None, eye: np.ndarray | None = None) -> np.ndarray:
        """An eye position from an angle (the rig's viewer distance and height) or as given,
        both checked against the limits of :mod:`viewcomp.calib.world.eye` (EyeError)."""
        if eye is not None:
            return check_eye(eye)
        if angle is None:
            raise EyeError("give a viewing angle or an eye position")
        angle = check_angle(angle)
        return self.rig.viewer.eye(angle)

    # -- the bundle ------------------------------------------------------------------------

    def save(self, path: str | Path) -> None:
        """Write the bundle atomically at exactly ``path``."""
        p, x = self.paper, self.pixel
        arrays = {
            "geometry.pos": p.geometry.pos,
            "geometry.refl": p.geometry.refl,
            "paper.n": p.n,
            "paper.means_c": np.stack([p.means_c[k] for k in (*CHANNEL_PATTERNS, "gray")]),
            "paper.ramp_cols_c": p.ramp_cols_c,
            "paper.w_tilde_w": p.w_tilde_w,
            "paper.rho_w": p.rho_w,
            "paper.ksis": p.fit.ksis,
            "paper.gamma": p.fit.gamma,
            "pixel.f_lut": x.f_lut,
            "pixel.Ww": x.white.W.astype(np.float32),
            "pixel.Aw": x.white.A.astype(np.float32),
            "pixel.Wc": x.screen.W.astype(np.float32),
            "pixel.Ac": x.screen.A.astype(np.float32),
            "pixel.kappa": x.lobe.kappa,
            "pixel.baseline": x.lobe.baseline,
        }
        meta = {
            "rig": rig_to_toml(self.rig),
            "geometry": {
                "projector": p.geometry.projector.tolist(),
                "camera": p.geometry.camera.tolist(),
            },
            "paper_fit": {
                "mode": p.fit.mode,
                "samples": p.fit.samples,
                "rms_log": p.fit.rms.tolist(),
                "r2": p.fit.r2.tolist(),
            },
            "pixel_fit": {
                "gamma": x.lobe.gamma,
                "rms": x.lobe.rms.tolist(),
                "rms_power_law": x.lobe.rms_power_law.tolist(),
                "samples": x.lobe.samples,
                "message": x.lobe.message,
                "response_rms": x.response_rms,
                "ambient_measured": x.screen.ambient_measured,
            },
            "info": self.info,
        }
        save_bundle(path, arrays, meta)

    @classmethod
    def load(cls, path: str | Path) -> Calibration:
        """Read a bundle written by ``save``.

        Raises:
            BundleError: unreadable, corrupt, of another schema, or missing a part.
        """
        arrays, meta = load_bundle(path, CALIBRATION_ARRAYS)
        try:
            rig = rig_from_dict(_toml_loads(meta["rig"]), source=f"{path} (rig)")
            g = ScreenGeometry(
                pos=arrays["geometry.pos"],
                refl=arrays["geometry.refl"],
                projector=np.asarray(meta["geometry"]["projector"], np.float64),
                camera=np.asarray(meta["geometry"]["camera"], np.float64),
            )
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
            paper = PaperCalibration(
                geometry=g,
                n=arrays["paper.n"],
                fit=fit,
                means_c={k: means[i] for i, k in enumerate((*CHANNEL_PATTERNS, "gray"))},
                ramp_cols_c=arrays["paper.ramp_cols_c"],
                w_tilde_w=arrays["paper.w_tilde_w"],
                rho_w=arrays["paper.rho_w"],
                rv90=g.rv(g.camera),
            )
            xf = meta["pixel_fit"]
            lobe = LobeFit(
                baseline=arrays["pixel.baseline"],
                kappa=arrays["pixel.kappa"],
                gamma=float(xf["gamma"]),
                rms=np.asarray(xf["rms"]),
                rms_power_law=np.asarray(xf["rms_power_law"]),
                samples=int(xf["samples"]),
                message=str(xf["message"]),
            )
            measured = bool(xf["ambient_measured"])
            pixel = PixelCalibration(
                geometry=g,
                f_lut=arrays["pixel.f_lut"],
                white=ScreenModel(arrays["pixel.Ww"], arrays["pixel.Aw"], measured),
                screen=ScreenModel(arrays["pixel.Wc"], arrays["pixel.Ac"], measured),
                lobe=lobe,
                response_rms=float(xf["response_rms"]),
            )
        except (KeyError, TypeError, ValueError) as e:
            raise BundleError(
                f"{path}: the bundle is incomplete or inconsistent ({e!r}): recalibrate with "
                "`viewcomp calibrate CAPTURE_DIR -o CALIB`"
            ) from e
        h, w = g.pos.shape[:2]
        if (w, h) != tuple(rig.projector.resolution):
            raise BundleError(
                f"{path}: maps are {w}x{h} but the rig's projector is "
                f"{rig.projector.resolution[0]}x{rig.projector.resolution[1]}: recalibrate"
            )
        return cls(rig=rig, paper=paper, pixel=pixel, info=dict(meta.get("info", {})))


def _toml_loads(text: str) -> dict[str, Any]:
    import tomllib

    return tomllib.loads(text)


def calibrate(
    cs: CaptureSet,
    fit_mode: str = "all",
    smooth_px: float = DEFAULT_SMOOTH_PX,
) -> Calibration:
    """Calibrate both methods from a loaded capture set.

    Captures in camera space (``[capture] space = "camera"``) are first rectified onto the
    projector grid (:mod:`viewcomp.calib.geo.rectify`: chessboard + Gray code); the geometric
    statistics go to ``info["geometry"]``.

    Raises:
        FitError: a capture that makes a fit impossible, naming it and what to do.
    """
    geometry_stats = None
    if cs.rig.capture.space != "projector":
        from viewcomp.calib.geo.rectify import (
            rectify_capture_set,  # camera frames -> the projector grid
        )

        cs, geometry_stats = rectify_capture_set(cs)
    check_captures(cs)
    t0 = time.perf_counter()
    geometry = ScreenGeometry.from_rig(cs.rig)
    white = {k: v.astype(np.float64) for k, v in cs.white.items()}
    screen = {k: v.astype(np.float64) for k, v in cs.screen.items()}
    missing = [k for k in REQUIRED if k not in white or k not in screen]
    if missing:
        raise FitError(f"white|screen/{missing[0]}", "missing from the capture set")
    paper = calibrate_paper(white, screen, geometry, fit_mode)
    pixel = calibrate_pixel(white, screen, geometry, smooth_px)
    info = {
        "captures": str(cs.path),
        "has_black": "black" in screen,
        "smooth_px": smooth_px,
        "seconds": round(time.perf_counter() - t0, 2),
    }
    if geometry_stats is not None:
        info["geometry"] = geometry_stats
    return Calibration(rig=cs.rig, paper=paper, pixel=pixel, info=info)
