"""Mono cameras (``Camera.channels == 1``): what their captures can and cannot calibrate.

A mono camera measures one band of light. Its frames are stored as three equal channels
(R = G = B, the same 0..1 scale as a colour capture), so the capture set's format and the
geometric calibration are unchanged. It can calibrate the geometry (chessboard, Gray code,
the camera-moved checks), the projector's and screen's overall response and the per-pixel
brightness (albedo as one grey level, vignetting, ambient light): every thing that is the same
in the three channels. It cannot see colour: the colour mixing matrix (how much each projector
primary adds to each camera channel), the screen's colour and any colour correction are
unmeasurable, so the live colour check only asks that each colour pattern lights the screen,
and `viewcomp calibrate` refuses a set whose captures are grey in every channel
(:func:`is_mono_set`) rather than fitting a mixing matrix from nothing.
"""

from __future__ import annotations

import numpy as np

from viewcomp.calib.hw.livechecks import LiveChecks
from viewcomp.calib.io.imageio import CaptureError

MONO_LIMITS = (
    "it calibrates the geometry and the brightness response, but cannot see colour (no colour "
    "mixing, no screen colour): the captures are stored as three equal channels and "
    "`viewcomp calibrate` refuses them for colour compensation; use a colour camera for that"
)


class MonoChecks(LiveChecks):
    """:class:`LiveChecks` for a mono camera: a colour pattern must light the screen more than
    gray does (its one channel rises), since which channel rises most cannot be seen."""

    def _colour(self, sub: str, rel: str, name: str, lin: np.ndarray) -> None:
        d = float((lin - self.gray[sub])[self.lit[sub]].mean())
        if not d > 0:
            raise CaptureError(
                f"{rel}: the {name} pattern does not light the screen more than gray does "
                f"(change {d:+.4f}): check that the window is on the projector"
            )


def is_mono_set(images: list[np.ndarray]) -> bool:
    """True when every (H, W, 3) image has R == G == B exactly (a mono camera's set)."""
    return bool(images) and all(
        np.array_equal(im[..., 0], im[..., 1]) and np.array_equal(im[..., 1], im[..., 2])
        for im in images
    )
