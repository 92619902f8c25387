"""Mono cameras (``Camera.channels == 1``): what their captures can and cannot calibrate.

A mono camera measures one band of light. Its frames are stored as three equal channels
(R = G = B, the same 0..1 scale as a colour capture), so the capture set's format is unchanged.
What such a set holds: the geometry (chessboard, Gray code, the camera-moved checks) and, per
pixel, one grey level of brightness response, albedo, vignetting and ambient light. What it
cannot hold is colour: how much each projector primary adds to each camera channel (the colour
mixing), the screen's colour, any colour correction. Capture therefore checks only that each
colour pattern lights the screen (:class:`~viewcomp.calib.hw.monochecks.MonoChecks`) and, before
writing, the geometry only; `viewcomp calibrate`, whose fits need the colour mixing, refuses a
set whose colour captures are grey in every channel (:func:`is_mono_set`,
:data:`MONO_REFUSAL`) rather than fitting a mixing matrix from nothing.
"""

from __future__ import annotations

import numpy as np

MONO_LIMITS = (
    "its captures hold the geometry and one grey level per pixel, not colour (no colour "
    "mixing, no screen colour): they are stored as three equal channels, and `viewcomp "
    "calibrate` refuses the set because its fits need the colour mixing; use a colour camera "
    "to calibrate compensation"
)


MONO_REFUSAL = (
    "the colour captures have R = G = B everywhere: a mono camera's set, which holds no colour "
    "and so no colour mixing to fit; capture again with a colour camera (a mono camera "
    "calibrates the geometry only)"
)


def is_mono_set(images: list[np.ndarray]) -> bool:
    """True when every (H, W, 3) image has R == G == B exactly (a mono camera's set)."""
    return bool(images) and all(
        np.array_equal(im[..., 0], im[..., 1]) and np.array_equal(im[..., 1], im[..., 2])
        for im in images
    )
