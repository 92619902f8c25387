"""The frame match behind the camera-moved checks: edges along which a pattern's light varies
(a ramp's frame under a glossy screen's lobe) must not pull the shift along them."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from viewcomp.calib.geo.framematch import MOVE_LIMIT_PX, frame_edges, frame_shift, lit_region

H, W = 180, 320
X0, X1, Y0, Y1 = 60, 260, 40, 140  # the projector's frame in the camera image


def _capture(pattern: str, dx: float, seed: int) -> np.ndarray:
    """A (H, W, 3) linear capture of a dark glossy laminate: the projector's frame lit by the
    pattern, seen through a lobe (a small highlight on a broad glow left of centre, the sides
    at a fifth of the glow's top, as bluebook's on a webcam), moved ``dx`` px by warpAffine
    (the truth), blurred and noisy as a camera's."""
    y, x = np.mgrid[0:H, 0:W].astype(np.float32)
    glow = np.exp(-(((x - 130.0) / 60.0) ** 2 + ((y - 90.0) / 60.0) ** 2))
    lobe = 0.2 + 0.6 * glow + 4.0 * np.exp(-((x - 130.0) ** 2 + (y - 90.0) ** 2) / 40.0)
    if pattern == "gray":
        drive = np.full((H, W), 0.5, np.float32)
    else:  # the ramp: black at the frame's left side, full at its right (linear light)
        drive = np.clip((x - X0) / (X1 - X0), 0.0, 1.0) ** 2.2
    frame = np.zeros((H, W), np.float32)
    frame[Y0:Y1, X0:X1] = 1.0
    img = (frame * drive * lobe * 0.05).astype(np.float32)
    img = cv2.warpAffine(img, np.float32([[1, 0, dx], [0, 1, 0]]), (W, H), flags=cv2.INTER_CUBIC)
    img = cv2.GaussianBlur(img, (0, 0), 1.0)
    img += np.random.default_rng(seed).normal(0.0, 2e-4, img.shape).astype(np.float32)
    return np.repeat(np.maximum(img, 0.0)[..., None], 3, axis=2)


@pytest.mark.parametrize("dx", [0.0, 1.5])
def test_a_ramp_under_a_lobe_is_matched_where_it_is(dx: float) -> None:
    """Matched as one gradient-magnitude image, the top and bottom edges - strongest where
    ramp times lobe is, right of where gray's are - pulled the still ramp 34 px sideways (per
    axis without the contrast) or the moved one 72 px (as one image)."""
    gray = _capture("gray", 0.0, 1)
    lit = lit_region(gray)
    shift = frame_shift(frame_edges(gray, lit), frame_edges(_capture("ramp", dx, 2), lit))
    assert shift.dx == pytest.approx(dx, abs=0.25), shift
    assert abs(shift.dy) < 0.25, shift
    assert (shift.distance > MOVE_LIMIT_PX) == (dx > MOVE_LIMIT_PX)
