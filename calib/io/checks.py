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
        _check_colours_against_gray(cs, sub)


def _check_colours_against_gray(cs: CaptureSet, sub: str) -> None:
    """Each colour pattern of Table 1 (130, or 255 in a camera capture, in its own channel,
    110 in the others) is brighter
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


MONO_REFUSAL = (
    "the colour captures have R = G = B everywhere: a mono camera's set, but without each "
    "projector primary shown alone (red_alone, ramp_red, ...), which a mono camera's fits need "
    "in place of colour; capture the set again with `viewcomp capture` (it takes them with a "
    "mono camera), or with a colour camera"
)
#: The least share of a capture's pixels that must be unclipped to judge it mono.
MONO_MIN_UNCLIPPED = 0.01


def is_mono_set(images: list[np.ndarray]) -> bool:
    """True when every (H, W, 3) linear image has R == G == B exactly on its unclipped pixels
    (every channel below 1.0, the top code): a mono camera's set. An image with fewer than
    :data:`MONO_MIN_UNCLIPPED` unclipped pixels says nothing (a saturated colour capture is
    grey too, and :func:`check_captures` refuses it naming ``--hdr``)."""
    if not images:
        return False
    for im in images:
        a = np.asarray(im)
        ok = a.max(axis=-1) < 1.0
        if ok.mean() < MONO_MIN_UNCLIPPED:
            return False
        r, g, b = a[..., 0][ok], a[..., 1][ok], a[..., 2][ok]
        if not (np.array_equal(r, g) and np.array_equal(g, b)):
            return False
    return True
