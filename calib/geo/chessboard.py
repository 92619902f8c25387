"""The projected chessboard: its corners in a camera image, and Zhang's method on them.

Camera and projector coordinates are pixels (x right, y down), pixel centres at integers.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from viewcomp.calib.errors import FitError
from viewcomp.calib.geo.captures import channel_mean
from viewcomp.calib.io.patterns import chessboard
from viewcomp.calib.world.geometry import screen_points_at
from viewcomp.calib.world.response import parse_response
from viewcomp.calib.world.rig import Rig

CHESSBOARD_SQUARES = (9, 6)  # patterns.chessboard's default: (columns, rows) of squares


@dataclass(frozen=True)
class Corners:
    """Detected chessboard corners: ``camera`` (N, 2) and ``projector`` (N, 2) pixels, in the
    order of :func:`~viewcomp.calib.io.patterns.chessboard` (row by row from the top-left)."""

    camera: np.ndarray
    projector: np.ndarray


def _to8(gray: np.ndarray) -> np.ndarray:
    """Linear (H, W) -> uint8 for OpenCV's detectors: normalised to the 99.9th percentile and
    sRGB-encoded (the detectors are tuned for such images; in linear light dark squares
    crowd the bottom codes and detection is marginal on small boards)."""
    top = float(np.percentile(gray, 99.9))
    if top <= 0:
        return np.zeros(gray.shape, np.uint8)
    enc = parse_response("srgb").encode(np.clip(gray / top, 0.0, 1.0))
    return np.rint(enc * 255.0).astype(np.uint8)


def find_corners(
    image: np.ndarray,
    projector_size: tuple[int, int],
    rel: str,
    shading: np.ndarray | None = None,
    black: np.ndarray | None = None,
) -> Corners:
    """The chessboard's inner corners in a camera image (Hc, Wc, 3) linear.

    ``shading`` (Hc, Wc, 3) linear: a capture of one uniform level on the same screen (the
    stage's gray), ``black`` (Hc, Wc, 3) its black, both optional. When the board is not found
    in ``image`` as it is, it is looked for in (image - black) / (shading - black): a glossy
    screen's highlight can light a black square as bright as the white ones around it (green
    plastic on a webcam), and the ratio takes the screen's own colour and lobe off, leaving
    the pattern. The corners are refined in the image they were found in.

    Raises:
        FitError: the chessboard is not found (``rel`` names the capture).
    """
    w, h = projector_size
    _, proj = chessboard(w, h, CHESSBOARD_SQUARES)
    pattern = (CHESSBOARD_SQUARES[0] - 1, CHESSBOARD_SQUARES[1] - 1)
    gray = channel_mean(image)
    g8 = _to8(gray)
    found = _detect(g8, pattern, len(proj))
    if found is None and shading is not None:
        gray = _over_shading(image, shading, black)
        g8 = _to8(gray)
        found = _detect(g8, pattern, len(proj))
    if found is None:
        raise FitError(
            rel,
            f"no chessboard with {pattern[0]}x{pattern[1]} inner corners found: the camera must "
            "see the whole projected chessboard, in focus, neither saturated nor too dark; "
            "check that this capture is the chessboard pattern, then capture it again",
        )
    crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 100, 1e-4)
    # the search window grows with the squares (a third of a side), so that the blurred
    # edges of a large, soft board fit in it
    grid = found.reshape(pattern[1], pattern[0], 2).astype(np.float64)
    spacing = float(np.median(np.linalg.norm(np.diff(grid, axis=1), axis=2)))
    half = int(np.clip(round(spacing / 3.0), 3, 30))
    found = cv2.cornerSubPix(g8, found.astype(np.float32), (half, half), (-1, -1), crit)
    cam = found.reshape(-1, 2).astype(np.float64)
    # OpenCV may list the corners from either end: the top-left square is black.
    hom, _ = cv2.findHomography(proj, cam)
    side = proj[1, 0] - proj[0, 0]
    probe = np.array(
        [proj[0] - 0.5 * side, proj[0] + [0.5 * side, -0.5 * side]], np.float64
    )  # centre of square (0, 0) (black) and of square (1, 0) (white)
    px = cv2.perspectiveTransform(probe[None], hom)[0]
    vals = [float(cv2.getRectSubPix(gray, (3, 3), (float(x), float(y))).mean()) for x, y in px]
    if vals[0] > vals[1]:
        cam = cam[::-1].copy()
    return Corners(camera=cam, projector=proj)


def _detect(g8: np.ndarray, pattern: tuple[int, int], n: int) -> np.ndarray | None:
    """OpenCV's corners of ``pattern`` (inner corners per row, per column) in ``g8`` (H, W)
    uint8, (n, 1, 2) float32, or None when not all ``n`` are found."""
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
    ok, found = cv2.findChessboardCorners(g8, pattern, flags=flags)
    if not ok or found is None or len(found) != n:
        ok, found = cv2.findChessboardCornersSB(g8, pattern)
    if not ok or found is None or len(found) != n:
        return None
    return np.asarray(found, np.float32)


def _over_shading(image: np.ndarray, shading: np.ndarray, black: np.ndarray | None) -> np.ndarray:
    """(H, W) float32: the channel mean of ``image`` over that of ``shading`` (black taken off
    both), the shading floored at 2 % of its 99th percentile so that the unlit surround reads
    about 0 rather than noise over noise."""
    img = channel_mean(image)
    ref = channel_mean(shading)
    if black is not None:
        dark = channel_mean(black)
        img = img - dark
        ref = ref - dark
    floor = max(0.02 * float(np.percentile(ref, 99.0)), 1e-6)
    return (np.maximum(img, 0.0) / np.maximum(ref, floor)).astype(np.float32)


def zhang(corners: Corners, rig: Rig) -> tuple[np.ndarray, np.ndarray, float]:
    """Zhang's method (``cv2.calibrateCamera``) on the chessboard's one planar view.

    The corners' world points come from the rig's projector; the camera matrix is the rig's
    and stays fixed (one view cannot determine it), as do tangential distortion and k3:
    (k1, k2) and the pose are estimated.

    Returns:
        (camera matrix (3, 3), distortion (5,) OpenCV order, reprojection RMS in camera px).
    """
    obj = screen_points_at(rig.projector, corners.projector).astype(np.float32)
    img = corners.camera.astype(np.float32)
    k0 = rig.camera.intrinsics()
    d0 = np.zeros(5) if rig.camera.distortion is None else np.asarray(rig.camera.distortion)
    flags = (
        cv2.CALIB_USE_INTRINSIC_GUESS
        | cv2.CALIB_FIX_FOCAL_LENGTH
        | cv2.CALIB_FIX_PRINCIPAL_POINT
        | cv2.CALIB_FIX_ASPECT_RATIO
        | cv2.CALIB_ZERO_TANGENT_DIST
        | cv2.CALIB_FIX_K3
    )
    rms, k, d, _, _ = cv2.calibrateCamera(
        [obj.reshape(-1, 1, 3)],
        [img.reshape(-1, 1, 2)],
        rig.camera.resolution,
        k0.copy(),
        d0.reshape(1, 5).copy(),
        flags=flags,
    )
    return np.asarray(k, np.float64), np.asarray(d, np.float64).ravel()[:5], float(rms)


def undistort_pixels(pts: np.ndarray, k: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """Camera pixels (N, 2) -> undistorted normalised coordinates (N, 2) (cv2.undistortPoints,
    iterated to convergence)."""
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-10)
    src = np.asarray(pts, np.float64).reshape(-1, 1, 2)
    out = cv2.undistortPoints(src, k, dist, None, None, None, crit)
    return out.reshape(-1, 2)
