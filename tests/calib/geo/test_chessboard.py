"""The chessboard's corners on a glossy screen whose highlight lights a black square brighter
than white ones: found in the capture over the stage's gray."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from viewcomp.calib.errors import FitError
from viewcomp.calib.geo.chessboard import find_corners
from viewcomp.calib.io.patterns import chessboard

PROJ = (160, 80)
CAM = (320, 180)
HOM = np.array([[1.55, 0.06, 32.0], [-0.03, 1.6, 22.0], [0.0, 0.0001, 1.0]])  # projector -> camera


def _seen(drive: np.ndarray) -> np.ndarray:
    """A projector image (h, w, 3) of drive levels 0..1, as a camera sees it on a glossy
    screen: linear light (the projector's black 2 % of white), warped into the camera, times a
    lobe whose highlight at the board's centre is 60 times the sides' light, blurred, with
    noise of 2 % of the sides' white; (Hc, Wc, 3)."""
    lin = 0.02 + 0.98 * drive.astype(np.float32) ** 2.2
    img = cv2.warpPerspective(lin, HOM, CAM, flags=cv2.INTER_AREA)
    y, x = np.mgrid[0 : CAM[1], 0 : CAM[0]].astype(np.float32)
    cx, cy = cv2.perspectiveTransform(np.float32([[[80.0, 40.0]]]), HOM)[0, 0]
    lobe = 1.0 / 60.0 + np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (2 * 9.0**2))
    img = cv2.GaussianBlur(img * lobe[..., None], (0, 0), 1.2)
    noise = np.random.default_rng(int(drive.sum()) % 1000).normal(0.0, 0.0003, img.shape)
    return np.maximum(img + noise, 0.0).astype(np.float32)


def test_a_highlight_that_hides_the_board_is_divided_out_by_gray() -> None:
    board, proj = chessboard(*PROJ)
    image = _seen(board / 255.0)
    gray = _seen(np.full_like(board, 128) / 255.0)
    black = _seen(np.zeros_like(board, dtype=np.float64))
    with pytest.raises(FitError, match="no chessboard"):  # as it is: the highlight hides it
        find_corners(image, PROJ, "screen/chessboard")
    found = find_corners(image, PROJ, "screen/chessboard", gray, black)
    truth = cv2.perspectiveTransform(proj[None].astype(np.float64), HOM)[0]
    rms = float(np.sqrt(np.mean(np.sum((found.camera - truth) ** 2, axis=1))))
    assert rms < 0.25, rms
