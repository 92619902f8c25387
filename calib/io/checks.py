"""Checks of a capture set before any fit: saturation and darkness, with the fix named."""

from __future__ import annotations

from viewcomp.calib.errors import FitError
from viewcomp.calib.io.captureset import CaptureSet

SATURATION_LIMIT = 0.005  # fraction of pixel-channels at the top code
DARK_LIMIT = 0.01  # mean linear level of the gray capture


def check_captures(cs: CaptureSet) -> None:
    """Refuse captures that make a fit impossible, naming the file and what to do.

    Raises:
        FitError: a saturated capture, a gray capture too dark to see, or no difference
            between the white and the real screen's setups.
    """
    for sub in ("white", "screen"):
        for name in cs.images(sub):
            frac = cs.saturated(sub, name)
            if frac > SATURATION_LIMIT:
                raise FitError(
                    f"{sub}/{name}",
                    f"{frac:.1%} of its pixel-channels are at the maximum code (saturated): "
                    "lower the camera's exposure or the projector's brightness and capture "
                    "again",
                )
        gray = cs.images(sub)["gray"]
        if float(gray.mean()) < DARK_LIMIT:
            raise FitError(
                f"{sub}/gray",
                f"too dark to measure (mean linear level {gray.mean():.4f}): raise the "
                "camera's exposure or darken the room less, and capture again",
            )
