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

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from viewcomp.calib.errors import FitError
from viewcomp.calib.fit.colourguide import guide_radius_for
from viewcomp.calib.fit.paper import PaperCalibration, calibrate_paper
from viewcomp.calib.fit.pixel import (
    DEFAULT_SMOOTH_PX,
    PixelCalibration,
    calibrate_pixel,
)
from viewcomp.calib.fit.quality import capture_quality, ramp_residual
from viewcomp.calib.geo.edgezone import edge_zone
from viewcomp.calib.io.bundle import BundleError
from viewcomp.calib.io.calibration_bundle import load_calibration, save_calibration
from viewcomp.calib.io.captureset import REQUIRED, CaptureSet
from viewcomp.calib.io.checks import MONO_REFUSAL, check_captures, is_mono_set
from viewcomp.calib.world.eye import ErrorClass, EyeError, check_angle, check_eye
from viewcomp.calib.world.geometry import ScreenGeometry
from viewcomp.calib.world.rig import Rig


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
        """Write the bundle atomically at exactly ``path``
        (:mod:`viewcomp.calib.io.calibration_bundle` has its layout)."""
        save_calibration(path, self.rig, self.paper, self.pixel, self.info)

    @classmethod
    def load(cls, path: str | Path) -> Calibration:
        """Read a bundle written by ``save``.

        Raises:
            BundleError: unreadable, corrupt, of another schema, or missing a part.
        """
        rig, paper, pixel, info = load_calibration(path)
        return cls(rig=rig, paper=paper, pixel=pixel, info=info)


def calibrate(
    cs: CaptureSet,
    fit_mode: str = "all",
    smooth_px: float = DEFAULT_SMOOTH_PX,
    lobe_param: str | None = None,
    maps: dict[str, np.ndarray] | None = None,
    log: Callable[[str], None] | None = None,
    guide_px: int | None = None,
) -> Calibration:
    """Calibrate both methods from a loaded capture set (``smooth_px``, ``guide_px``:
    :func:`~viewcomp.calib.fit.pixel.calibrate_pixel`'s; ``guide_px`` None: the set's
    space's, :func:`~viewcomp.calib.fit.colourguide.guide_radius_for`).

    How good the captures were (exposure, noise, the per-pixel model's residual on the ramp:
    :func:`~viewcomp.calib.fit.quality.capture_quality`) goes to ``info["quality"]``; given a
    dict ``maps``, the per-pixel residual map (H, W) float32 is put in it as
    ``"ramp_residual"`` (for `calibrate --report`). ``log`` hears each stage as it starts.

    Captures in camera space (``[capture] space = "camera"``) are first rectified onto the
    projector grid (:mod:`viewcomp.calib.geo.rectify`: chessboard + Gray code; statistics in
    ``info["geometry"]``). Pixels clipped in any capture (8-bit at the top code) are left out
    of the lobe fit and of the paper's statistics; more than that can absorb is refused
    (:func:`~viewcomp.calib.io.checks.check_captures`, naming ``--hdr``).

    Raises:
        FitError: a capture that makes the per-pixel method impossible, naming it and what
            to do. The paper's method failing is not an error: the calibration then holds
            the per-pixel method alone and ``info["paper_error"]`` says why.
    """
    say = log or (lambda _msg: None)
    guide_px = guide_radius_for(cs.rig.capture.space) if guide_px is None else guide_px
    geometry_stats = None
    mono = _is_mono(cs)
    if cs.rig.capture.space != "projector":
        say("rectifying the camera's captures onto the projector grid (chessboard, Gray code)")
        from viewcomp.calib.geo.rectify import rectify_capture_set  # camera -> projector grid

        cs, geometry_stats = rectify_capture_set(cs, check_order=not mono)
    cs, mono_info = _per_primary_set(cs, say) if mono else (cs, {})
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
    say("fitting the per-pixel method (colour mixing, response, specular lobe)")
    # a camera-space set's edge zone holds copies: the lobe's fit leaves it out
    filled = (
        None if geometry_stats is None else edge_zone(clipped.shape, geometry_stats["edge_zone_px"])
    )
    pixel = calibrate_pixel(
        white, screen, geometry, smooth_px, ~clipped, lobe_param, guide_px, filled
    )
    info: dict[str, Any] = {
        "captures": str(cs.path),
        "has_black": "black" in screen,
        "smooth_px": smooth_px,
        "colour_guide_px": guide_px,
        "clipped_pixels": int(np.count_nonzero(clipped)),
        "quality": capture_quality(pixel, white, screen),
    }
    if maps is not None:
        maps["ramp_residual"] = ramp_residual(pixel, screen["ramp"])
    say("fitting the paper's method")
    try:
        paper = calibrate_paper(white, screen, geometry, fit_mode, _stat_mask(pixel, clipped))
    except FitError as exc:
        paper = None
        info["paper_error"] = str(exc)
    info["seconds"] = round(time.perf_counter() - t0, 2)
    if geometry_stats is not None:
        info["geometry"] = geometry_stats
    info.update({"mono": mono_info} if mono else {})
    return Calibration(rig=cs.rig, paper=paper, pixel=pixel, info=info)


def _stat_mask(pixel: PixelCalibration, clipped: np.ndarray) -> np.ndarray:
    """(H, W) bool: the pixels the paper's image-wide statistics use - not clipped and off
    the highlight (where the fitted lobe seen by the camera exceeds a quarter of the diffuse
    level), or all unclipped ones where that leaves under half the frame."""
    geometry = pixel.geometry
    lobe_cam = pixel.lobe.at(geometry, geometry.camera)
    mask = ~clipped & np.all(lobe_cam <= 0.25 * np.maximum(pixel.lobe.baseline, 1e-6), -1)
    return mask if np.mean(mask) >= 0.5 else ~clipped


def _is_mono(cs: CaptureSet) -> bool:
    """Whether ``cs`` is a mono camera's set (grey colour captures).

    Raises:
        FitError: a mono set without the primaries shown alone (:data:`MONO_REFUSAL`).
    """
    mono = is_mono_set([cs.white[n] for n in ("red", "green", "blue") if n in cs.white])
    if mono and "red_alone" not in cs.white:
        raise FitError("white/red", MONO_REFUSAL)
    return mono


def _per_primary_set(
    cs: CaptureSet, say: Callable[[str], None]
) -> tuple[CaptureSet, dict[str, float]]:
    """A mono camera's set (on the projector grid) with its Table 1 captures in the
    per-primary basis (:mod:`viewcomp.calib.fit.mono`), and each stage's additivity misfit."""
    from dataclasses import replace

    from viewcomp.calib.fit.mono import per_primary_images

    say("a mono camera's set: the captures in the per-primary basis (docs/MODEL.md)")

    white, add_w = per_primary_images(cs.white, "white")
    screen, add_s = per_primary_images(cs.screen, "screen")
    return replace(cs, white=white, screen=screen), {
        "additivity_white": round(add_w, 4),
        "additivity_screen": round(add_s, 4),
    }
