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
        _check_colours_against_gray(cs, sub)


def _check_colours_against_gray(cs: CaptureSet, sub: str) -> None:
    """Each colour pattern of Table 1 (130 in its own channel, 110 in the others) is brighter
    than gray (110 everywhere) in its own channel on any screen. When all three are not,
    the gray capture is the odd one; when one is not, that pair is named."""
    images = cs.images(sub)
    gray = images["gray"].reshape(-1, 3).mean(axis=0)
    diffs = {
        name: float(images[name].reshape(-1, 3).mean(axis=0)[j] - gray[j])
        for j, name in enumerate(("red", "green", "blue"))
    }
    bad = [name for name, d in diffs.items() if d <= 1e-6]
    if len(bad) == 3:
        raise FitError(
            f"{sub}/gray",
            "it is as bright as or brighter than red, green and blue in their own channels, so "
            "it is not a capture of the gray pattern (110,110,110) at the set's exposure - "
            f"capture {sub}/gray again with the gray pattern projected and the exposure locked",
        )
    if bad:
        name = bad[0]
        raise FitError(
            f"{sub}/{name}",
            f"not brighter than {sub}/gray in its own channel (difference {diffs[name]:.2g}): "
            f"one of {sub}/{name} and {sub}/gray is not the pattern it is named for, or the "
            "exposure or white balance changed between them - capture both again with the "
            "camera's exposure and white balance locked",
        )
