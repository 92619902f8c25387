"""Checks of a capture set before any fit: saturation and darkness, with the fix named.

The white screen is matte: a clipped white capture means the exposure is too high. On the
real screen a glossy highlight may clip in 8-bit while the diffuse level is well exposed: up
to ``MASK_LIMIT`` of the pixels clipped are left out of the fits (the calibration reports
how many); more is refused, naming ``--hdr`` (bracketed exposures merged into linear float
captures, which never clip).
"""

from __future__ import annotations

import numpy as np

from viewcomp.calib.errors import FitError
from viewcomp.calib.io.captureset import CaptureSet

SATURATION_LIMIT = 0.005  # fraction of pixel-channels at the top code, white screen
MASK_LIMIT = 0.05  # fraction of pixels clipped on the real screen that the fits leave out
DARK_LIMIT = 0.002  # mean linear level of the gray capture


def check_captures(cs: CaptureSet) -> None:
    """Refuse captures that make a fit impossible, naming the file and what to do.

    Raises:
        FitError: a saturated white capture, a real-screen capture clipped over more than
            ``MASK_LIMIT`` of its pixels, or a gray capture too dark to measure.
    """
    for sub in ("white", "screen"):
        for name in cs.images(sub):
            frac = cs.saturated(sub, name)
            if frac <= SATURATION_LIMIT:
                continue
            mask = cs.clipped.get((sub, name))
            pixels = float(np.mean(mask)) if mask is not None else frac
            if sub == "screen" and pixels <= MASK_LIMIT:
                continue  # the highlight: left out of the fits (calibrate says how much)
            raise FitError(
                f"{sub}/{name}",
                f"{frac:.1%} of its pixel-channels ({pixels:.1%} of the pixels) are at the "
                "maximum code (saturated): lower the camera's exposure until nothing clips, "
                "or capture with --hdr (bracketed exposures hold a highlight tens of times the "
                "diffuse level), and capture again",
            )
        gray = cs.images(sub)["gray"]
        if float(gray.mean()) < DARK_LIMIT:
            raise FitError(
                f"{sub}/gray",
                f"too dark to measure (mean linear level {gray.mean():.4f}): raise the "
                "camera's exposure or darken the room less, and capture again; if a highlight "
                "forces the exposure down, capture with --hdr",
            )
