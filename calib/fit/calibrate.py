"""From a capture set to a calibration bundle, and back: both methods in one file.

``calibrate(capture_set)`` runs the per-pixel method and the paper's method on the same
linearised captures and checks them first (saturation, darkness, size). Pixels clipped in an
8-bit capture are left out of the fits. The per-pixel method is required; the paper's method
is kept when it fits, and when it does not the bundle holds the per-pixel method alone and
says why (``Calibration.methods``, ``info["paper_error"]``). ``Calibration`` saves to and
loads from the bundle (``viewcomp.calib.io.bundle``: a zip of .npy arrays and JSON, no pickle,
atomic).
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
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
from viewcomp.calib.io.compact import decode_screen, encode_screen
from viewcomp.calib.model.lobe import LOBE_N, LOBE_PARAMS
from viewcomp.calib.world.eye import ErrorClass, EyeError, check_angle, check_eye
from viewcomp.calib.world.geometry import ScreenGeometry
from viewcomp.calib.world.rig import Rig, rig_from_dict, rig_to_toml


@dataclass
class Calibration:
    """Both methods' calibrations for one rig, plus what the fits said."""

    rig: Rig
    paper: PaperCalibration | None
    pixel: PixelCalibration
    info: dict[str, Any]

    @property
    def shape(self) -> tuple[int, int]:
        """(H, W) of the projector grid."""
        return self.pixel.geometry.pos.shape[:2]

    @property
    def methods(self) -> tuple[str, ...]:
        """The methods this calibration holds: ("pixel", "paper") or ("pixel",)."""
        return ("pixel",) if self.paper is None else ("pixel", "paper")

    def require(self, method: str) -> None:
        """Refuse a method this calibration does not hold, saying why and what to do.

        Raises:
            BundleError: ``method`` is "paper" and the paper's method did not fit.
        """
        if method == "paper" and self.paper is None:
            why = self.info.get("paper_error", "it was not fitted")
            raise BundleError(
                f"this calibration holds only the per-pixel method: the paper's method did not "
                f"fit ({why}); use --method pixel, or recalibrate with captures it can fit"
            )

    def eye(
        self,
        angle: float | None = None,
        eye: Sequence[float] | np.ndarray | None = None,
        error: ErrorClass = EyeError,
    ) -> np.ndarray:
        """An eye position from an angle (the rig's viewer distance and height) or as given,
        both checked against the limits of :mod:`viewcomp.calib.world.eye` (``error``,
        EyeError unless the caller names its own)."""
        if eye is not None:
            return check_eye(eye, error=error)
        if angle is None:
            raise error("give a viewing angle or an eye position")
        angle = check_angle(angle, error=error)
        return self.rig.viewer.eye(angle)

    # -- the bundle ------------------------------------------------------------------------

    def save(self, path: str | Path) -> None:
        """Write the bundle atomically at exactly ``path``."""
        p, x = self.paper, self.pixel
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
            "rig": rig_to_toml(self.rig),
            "methods": list(self.methods),
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
            "info": self.info,
        }
        if p is not None:
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

    @classmethod
    def load(cls, path: str | Path) -> Calibration:
        """Read a bundle written by ``save``.

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
            paper = None
            if "paper" in meta["methods"]:
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
                    stat_mask=arrays["paper.stat_mask"].astype(bool),
                )
            xf = meta["pixel_fit"]
            lobe = LobeFit(
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
        return cls(rig=rig, paper=paper, pixel=pixel, info=dict(meta.get("info", {})))


def finite_list(a: np.ndarray) -> list[float | None]:
    """JSON-safe floats: NaN (a comparison fit that could not run) as None (null)."""
    return [float(v) if np.isfinite(v) else None for v in np.asarray(a, np.float64)]


def _toml_loads(text: str) -> dict[str, Any]:
    import tomllib

    return tomllib.loads(text)


def calibrate(
    cs: CaptureSet,
    fit_mode: str = "all",
    smooth_px: float = DEFAULT_SMOOTH_PX,
    lobe_param: str | None = None,
) -> Calibration:
    """Calibrate both methods from a loaded capture set.

    Captures in camera space (``[capture] space = "camera"``) are first rectified onto the
    projector grid (:mod:`viewcomp.calib.geo.rectify`: chessboard + Gray code); the geometric
    statistics go to ``info["geometry"]``.

    Pixels clipped in any capture (8-bit at the top code) are left out of the lobe fit and of
    the paper's statistics; :func:`~viewcomp.calib.io.checks.check_captures` refuses captures
    with more clipped than that can absorb, naming ``--hdr``.

    Raises:
        FitError: a capture that makes the per-pixel method impossible, naming it and what
            to do. The paper's method failing is not an error: the calibration then holds
            the per-pixel method alone and ``info["paper_error"]`` says why.
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
    # The captures as loaded (float32, the capture set's own arrays: no copies, which at
    # 3840x2160 would be 2.4 GB in float64); the fits' sums and solves run in float64.
    white = {k: np.asarray(v, np.float32) for k, v in cs.white.items()}
    screen = {k: np.asarray(v, np.float32) for k, v in cs.screen.items()}
    missing = [k for k in REQUIRED if k not in white or k not in screen]
    if missing:
        raise FitError(f"white|screen/{missing[0]}", "missing from the capture set")
    clipped = cs.clipped_pixels()
    pixel = calibrate_pixel(white, screen, geometry, smooth_px, ~clipped, lobe_param)
    info: dict[str, Any] = {
        "captures": str(cs.path),
        "has_black": "black" in screen,
        "smooth_px": smooth_px,
        "clipped_pixels": int(np.count_nonzero(clipped)),
    }
    # The paper's image-wide statistics leave out the highlight (where the fitted lobe seen
    # by the camera exceeds a quarter of the diffuse level) and clipped pixels.
    lobe_cam = pixel.lobe.at(geometry, geometry.camera)
    stat_mask = ~clipped & np.all(lobe_cam <= 0.25 * np.maximum(pixel.lobe.baseline, 1e-6), -1)
    del lobe_cam
    if np.mean(stat_mask) < 0.5:
        stat_mask = ~clipped
    try:
        paper = calibrate_paper(white, screen, geometry, fit_mode, stat_mask)
    except FitError as exc:
        paper = None
        info["paper_error"] = str(exc)
    info["seconds"] = round(time.perf_counter() - t0, 2)
    if geometry_stats is not None:
        info["geometry"] = geometry_stats
    return Calibration(rig=cs.rig, paper=paper, pixel=pixel, info=info)
