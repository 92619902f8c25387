"""Geometric calibration of a camera-space capture set: from camera frames to the projector grid.

With ``[capture] space = "camera"`` the captures are raw camera frames (Hc, Wc, 3): the
projector's frame is a distorted quadrilateral in them. Before any of docs/MODEL.md's math, every
capture is rectified onto the projector's pixel grid (H, W), as the paper does with Zhang's
method and a chessboard:

1. **Chessboard** (``screen/chessboard``, and ``white/chessboard`` when present):
   ``cv2.findChessboardCorners`` + ``cv2.cornerSubPix``; the corners' projector coordinates
   are known (:func:`~viewcomp.calib.io.patterns.chessboard`), their points on the screen come
   from the rig's projector. Zhang's method (``cv2.calibrateCamera``) on that one planar
   view, seeded with the rig's intrinsics which stay fixed (one view cannot determine them),
   estimates the lens distortion (k1, k2) and gives the reprojection error.
2. **Gray code** (``screen/graycode_white``, ``graycode_black``, ``graycode_00`` ...; OpenCV
   structured_light's patterns): decoded per camera pixel into the projector column and row
   that light it. Each bit plane is first checked against the chessboard's prediction, so a
   plane out of order is named.
3. **The map** projector pixel -> camera pixel, a smooth model fitted to the decoded pixels
   (robust least squares, started from Zhang's lens and the chessboard's homography):
   camera = K dist(H [s, t, 1]) + r(s, t), with (s, t) the projector pixel scaled to -1..1,
   K the rig's camera matrix, dist OpenCV's (k1, k2, p1, p2) lens refined on the dense
   points, H a homography (exact for a pinhole projector on a plane) and r a cubic
   polynomial correction (what the projector's own lens adds). The Gray code quantises to
   whole projector pixels; the fit over ~10^4 pixels averages that away.
4. **Rectification**: ``cv2.remap`` (bilinear) of every Table-1 capture through the map gives
   float32 (H, W, 3) linear images on the projector grid, as a ``space = "projector"`` set;
   the frame's outermost ring of pixels, seen half against the unlit surround, copies its
   inner neighbours (:func:`fill_border`).

The camera's response comes from rig.toml. It is checked against the captures: light adds
up, so a Gray-code plane and its inverse, linearised, must sum to white + black even where
the optics blur a stripe edge to an intermediate value; :func:`estimate_response` finds the
response ("linear", "srgb" or a power law) that makes them do so, and a rig response that
misfits grossly is refused with the estimate in the message.

Refusals (:class:`~viewcomp.calib.errors.FitError`, naming the capture and the fix): no
chessboard; Gray code missing, out of order or not covering the projector image; Table-1
captures in the wrong order (or one as dark as black); a saturated chessboard; the camera
moved between captures (the projector frame's edges or the chessboard corners shift by more
than :data:`MOVE_LIMIT_PX`); the projector image not wholly in the camera's view; a wrong
camera response.

Units: camera and projector coordinates are pixels, (x right, y down), pixel centres at
integers; image arrays are indexed ``[row, column]``.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from scipy.optimize import least_squares

from viewcomp.calib.errors import FitError
from viewcomp.calib.io.captureset import OPTIONAL, REQUIRED, CaptureSet
from viewcomp.calib.io.checks import SATURATION_LIMIT
from viewcomp.calib.io.imageio import CaptureError, max_code_fraction, read_image
from viewcomp.calib.io.patterns import chessboard, graycode_patterns
from viewcomp.calib.world.response import Response, parse_response
from viewcomp.calib.world.rig import Device, Rig

CHESSBOARD_SQUARES = (9, 6)  # patterns.chessboard's default: (columns, rows) of squares
MOVE_LIMIT_PX = 1.0  # camera pixels: a larger shift between captures means the camera moved
BIT_CONTRAST = 0.08  # |pattern - inverse| / (white - black) below which a bit is unreliable
BIT_AGREEMENT = 0.8  # a Gray-code plane must agree with the chessboard on this share of pixels
MIN_DECODED = 0.5  # share of the lit projector frame that must decode
COVERAGE_CELLS = (16, 8)  # every cell of this grid over the projector image must decode
MAX_DENSE_POINTS = 12000
MIN_PEAK = 0.1  # phase-correlation peak below which two captures do not show the same frame
BORDER_PX = 1  # projector pixels at the frame's edge, seen half against the unlit surround
POLY_ORDER = 3
RESPONSE_SAMPLES = 60000  # stripe-edge pixels used to check the camera's response
RESPONSE_GAMMAS = (1.0, 3.5)  # the range of power laws tried
RESPONSE_REFUSE = (0.05, 4.0)  # refuse the rig's response above this misfit and ratio to best

_GEOMETRIC_FIX = (
    "capture it with `viewcomp capture` (or project the patterns of `viewcomp patterns` in "
    "that order)"
)


# ---------------------------------------------------------------------------------------------
# Small geometry helpers


def screen_points_at(projector: Device, uv: np.ndarray) -> np.ndarray:
    """Points on the screen z = 0 lit by projector pixels: (..., 2) (u, v) -> (..., 3) metres.

    The projector is the rig's pinhole (no lens distortion). Raises ``ValueError`` when a ray
    does not meet the screen in front of the projector.
    """
    p = np.asarray(uv, np.float64)
    if p.shape[-1:] != (2,):
        raise ValueError(f"uv must have shape (..., 2), got {p.shape}")
    f = projector.focal()
    cx, cy = projector.principal()
    rot, _ = projector.pose()
    d_dev = np.stack([(p[..., 0] - cx) / f, (p[..., 1] - cy) / f, np.ones(p.shape[:-1])], -1)
    d = d_dev @ rot
    origin = np.asarray(projector.position, np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -origin[2] / d[..., 2]
    if not np.all(np.isfinite(t)) or np.any(t <= 0):
        raise ValueError("some projector rays do not meet the screen plane z = 0 in front")
    pts = origin + t[..., None] * d
    pts[..., 2] = 0.0
    return pts


def distort_normalised(xn: np.ndarray, yn: np.ndarray, dist: np.ndarray) -> tuple[np.ndarray, ...]:
    """OpenCV's lens model on normalised coordinates: (k1, k2, p1, p2, k3) -> distorted (x, y)."""
    k1, k2, p1, p2, k3 = (float(v) for v in dist)
    r2 = xn * xn + yn * yn
    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    xd = xn * radial + 2.0 * p1 * xn * yn + p2 * (r2 + 2.0 * xn * xn)
    yd = yn * radial + p1 * (r2 + 2.0 * yn * yn) + 2.0 * p2 * xn * yn
    return xd, yd


def _apply_h(h: np.ndarray, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    w = h[2, 0] * x + h[2, 1] * y + h[2, 2]
    return (h[0, 0] * x + h[0, 1] * y + h[0, 2]) / w, (h[1, 0] * x + h[1, 1] * y + h[1, 2]) / w


def _poly_basis(s: np.ndarray, t: np.ndarray, order: int = POLY_ORDER) -> np.ndarray:
    """Monomials s^i t^j, i + j <= order: (..., n_terms)."""
    return np.stack([s**i * t**j for i in range(order + 1) for j in range(order + 1 - i)], -1)


@dataclass(frozen=True)
class ProjectorMap:
    """Projector pixel -> camera pixel: camera = K dist(H [s, t, 1]) + r(s, t).

    (s, t) are the projector coordinates normalised to -1..1 over the frame (s = (u - cu) / cu
    with cu = (W - 1) / 2, likewise t). ``camera_matrix`` (3, 3) and ``distortion`` (5,) are
    the camera's lens (OpenCV conventions); ``homography`` (3, 3) maps (s, t) to undistorted
    normalised camera coordinates; ``residual`` (2, n_terms) is the cubic correction r in
    camera pixels. ``size`` is the projector's (W, H).
    """

    camera_matrix: np.ndarray
    distortion: np.ndarray
    homography: np.ndarray
    residual: np.ndarray
    size: tuple[int, int]

    def _st(self, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        cu, cv = (self.size[0] - 1) / 2.0, (self.size[1] - 1) / 2.0
        return (uv[..., 0] - cu) / cu, (uv[..., 1] - cv) / cv

    def __call__(self, uv: np.ndarray) -> np.ndarray:
        """Camera pixels (..., 2) float64 of projector points (..., 2) (u, v) in pixels."""
        p = np.asarray(uv, np.float64)
        if p.shape[-1:] != (2,):
            raise ValueError(f"uv must have shape (..., 2), got {p.shape}")
        s, t = self._st(p)
        return _model(self.camera_matrix, self.distortion, self.homography, s, t) + np.einsum(
            "...k,ck->...c", _poly_basis(s, t), self.residual
        )

    def grid(self) -> tuple[np.ndarray, np.ndarray]:
        """``cv2.remap`` maps (map_x, map_y), each (H, W) float32: the camera pixel that every
        projector pixel centre is seen at."""
        w, h = self.size
        uu, vv = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
        cam = self(np.stack([uu, vv], -1))
        return cam[..., 0].astype(np.float32), cam[..., 1].astype(np.float32)


def _model(
    k: np.ndarray, dist: np.ndarray, h: np.ndarray, s: np.ndarray, t: np.ndarray
) -> np.ndarray:
    xn, yn = _apply_h(h, s, t)
    xd, yd = distort_normalised(xn, yn, dist)
    return np.stack([k[0, 0] * xd + k[0, 2], k[1, 1] * yd + k[1, 2]], -1)


def rectify(image: np.ndarray, maps: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Resample a camera image (Hc, Wc, C) onto the projector grid: (H, W, C) float32 (bilinear;
    points outside the camera image take the nearest edge value)."""
    return cv2.remap(
        np.ascontiguousarray(image, np.float32),
        maps[0],
        maps[1],
        cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_REPLICATE,
    )


def fill_border(image: np.ndarray, n: int) -> np.ndarray:
    """Copy the ``n`` outermost rows and columns of a projector-grid image (H, W, C) from their
    nearest inner neighbours, in place; returns it.

    The camera sees the frame's outermost projector pixels half against the unlit surround
    (its optics blur by about a pixel), so they read ~20% dark; their neighbours do not.
    """
    if n <= 0:
        return image
    h, w = image.shape[:2]
    if h <= 2 * n or w <= 2 * n:
        raise ValueError(f"an image of {w}x{h} has no interior inside a {n}-pixel border")
    image[:n] = image[n]
    image[h - n :] = image[h - n - 1]
    image[:, :n] = image[:, n : n + 1]
    image[:, w - n :] = image[:, w - n - 1 : w - n]
    return image


# ---------------------------------------------------------------------------------------------
# Loading the geometric captures


def _lut_linear(raw: np.ndarray, response: Response) -> np.ndarray:
    """Raw (H, W, 3) -> float32 linear, exactly as imageio.to_linear but through a table."""
    if raw.dtype == np.uint8:
        return response.decode(np.arange(256, dtype=np.float32) / 255.0)[raw]
    if raw.dtype == np.uint16:
        return response.decode(np.arange(65536, dtype=np.float32) / 65535.0)[raw]
    return raw.astype(np.float32, copy=False)


class _Captures:
    """The images of one sub-folder of a capture set, loaded on demand (linear float32)."""

    def __init__(self, cs: CaptureSet, sub: str) -> None:
        self.cs = cs
        self.sub = sub
        self.response = cs.rig.camera.response_curve()
        self.memory: Mapping[str, np.ndarray] = cs.images(sub)
        self.files = {p.stem: p for p in cs.extra.get(sub, [])}
        self.saturation: dict[str, float] = {}

    def has(self, name: str) -> bool:
        return name in self.memory or name in self.files

    def rel(self, name: str) -> str:
        p = self.files.get(name)
        return f"{self.sub}/{p.name}" if p is not None else f"{self.sub}/{name}"

    def get(self, name: str) -> np.ndarray:
        """(Hc, Wc, 3) float32 linear; raises FitError when missing."""
        if name in self.memory:
            key = (self.sub, name)
            self.saturation[name] = self.cs.raw_max_fraction.get(key, 0.0)
            return np.asarray(self.memory[name], np.float32)
        if name not in self.files:
            raise FitError(
                f"{self.sub}/{name}.png",
                f"not found: camera-space capture sets need it; {_GEOMETRIC_FIX}",
            )
        try:
            raw = read_image(self.files[name])
        except CaptureError as exc:
            raise FitError(self.rel(name), str(exc)) from None
        cw, ch = self.cs.rig.camera.resolution
        if raw.shape[:2] != (ch, cw):
            raise FitError(
                self.rel(name),
                f"is {raw.shape[1]}x{raw.shape[0]}, the camera's resolution is {cw}x{ch}: "
                "capture every image of the set with the same camera settings",
            )
        self.saturation[name] = max_code_fraction(raw)
        return _lut_linear(raw, self.response)


def _gray(img: np.ndarray) -> np.ndarray:
    """(H, W, 3) -> (H, W) float32 mean of the channels."""
    a = np.asarray(img, np.float32)
    return (a[..., 0] + a[..., 1] + a[..., 2]) * np.float32(1.0 / 3.0)


# ---------------------------------------------------------------------------------------------
# Chessboard and Zhang


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


def find_corners(image: np.ndarray, projector_size: tuple[int, int], rel: str) -> Corners:
    """The chessboard's inner corners in a camera image (Hc, Wc, 3) linear.

    Raises:
        FitError: the chessboard is not found (``rel`` names the capture).
    """
    w, h = projector_size
    _, proj = chessboard(w, h, CHESSBOARD_SQUARES)
    pattern = (CHESSBOARD_SQUARES[0] - 1, CHESSBOARD_SQUARES[1] - 1)
    g8 = _to8(_gray(image))
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
    ok, found = cv2.findChessboardCorners(g8, pattern, flags=flags)
    if not ok or found is None or len(found) != len(proj):
        ok, found = cv2.findChessboardCornersSB(g8, pattern)
    if not ok or found is None or len(found) != len(proj):
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
    gray = _gray(image)
    vals = [float(cv2.getRectSubPix(gray, (3, 3), (float(x), float(y))).mean()) for x, y in px]
    if vals[0] > vals[1]:
        cam = cam[::-1].copy()
    return Corners(camera=cam, projector=proj)


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


# ---------------------------------------------------------------------------------------------
# Gray code


@dataclass(frozen=True)
class GrayCode:
    """The decoded Gray code: per camera pixel (Hc, Wc) the projector ``column`` and ``row``
    (int32, -1 where not decoded), ``lit`` (bool: the projector lights the pixel), the
    per-plane ``bits`` (n_planes // 2, Hc, Wc) bool and ``reliable`` (same shape, bool), and
    ``response_samples``: pixels on a blurred stripe edge, for :func:`estimate_response`."""

    column: np.ndarray
    row: np.ndarray
    lit: np.ndarray
    bits: np.ndarray
    reliable: np.ndarray
    names: tuple[str, ...]
    n_col_bits: int
    col_bits: np.ndarray  # (n_col_bits, W) bool: plane k's bit for each projector column
    row_bits: np.ndarray  # (n_row_bits, H) bool
    response_samples: np.ndarray  # (N, 4, 3) linear: plane, inverse, white, black at a pixel


def graycode_names(w: int, h: int) -> list[str]:
    """Capture names of the Gray-code planes for a w x h projector (graycode_00 ...)."""
    n = len(graycode_patterns(w, h)[0])
    digits = max(2, len(str(n - 1)))
    return [f"graycode_{k:0{digits}d}" for k in range(n)]


def _lit_mask(white: np.ndarray, black: np.ndarray, rel: str) -> tuple[np.ndarray, float]:
    """(Hc, Wc) bool where the projector lights the screen (white - black above a quarter of
    its 99.5th percentile), and that percentile. Raises FitError if nothing is lit."""
    rng = white - black
    top = float(np.percentile(rng, 99.5))
    if top <= 0.02:
        raise FitError(
            rel,
            f"the projector is not visible (white - black is at most {top:.3f} in linear units): "
            "point the camera at the projected image, raise the exposure, and capture again",
        )
    return rng > 0.25 * top, top


def decode_graycode(
    caps: _Captures,
    projector_size: tuple[int, int],
    on_pair: Callable[[str, np.ndarray], None] | None = None,
) -> GrayCode:
    """Decode OpenCV's Gray-code captures into projector column and row per camera pixel.

    A bit is the comparison of a plane with its inverse, reliable where their difference is
    at least :data:`BIT_CONTRAST` of white - black; a pixel decodes where every bit is.
    ``on_pair(name, plane + inverse)`` sees each pair as it is loaded (the sum is all lit).

    Raises:
        FitError: a missing plane, or a projector too dim to see in graycode_white.
    """
    w, h = projector_size
    planes, _, _ = graycode_patterns(w, h)
    names = graycode_names(w, h)
    n_col = int(np.ceil(np.log2(w)))
    n_pairs = len(planes) // 2
    white = _gray(caps.get("graycode_white"))
    black = _gray(caps.get("graycode_black"))
    rng = white - black
    lit, top = _lit_mask(white, black, caps.rel("graycode_white"))
    bits = np.zeros((n_pairs, *rng.shape), bool)
    reliable = np.zeros((n_pairs, *rng.shape), bool)
    floor = np.maximum(rng, 0.05 * top)
    white3, black3 = caps.get("graycode_white"), caps.get("graycode_black")
    samples = []
    per_pair = RESPONSE_SAMPLES // max(n_pairs, 1)
    for k in range(n_pairs):
        pos3, neg3 = caps.get(names[2 * k]), caps.get(names[2 * k + 1])
        pos, neg = _gray(pos3), _gray(neg3)
        diff = pos - neg
        bits[k] = diff > 0
        reliable[k] = np.abs(diff) >= BIT_CONTRAST * floor
        # pixels the optics blur across a stripe edge see part of each: response samples
        t = (pos - black) / floor
        ys, xs = np.nonzero(lit & (t > 0.15) & (t < 0.85))
        step = max(1, int(np.ceil(len(xs) / max(per_pair, 1))))
        ys, xs = ys[::step], xs[::step]
        samples.append(np.stack([pos3[ys, xs], neg3[ys, xs], white3[ys, xs], black3[ys, xs]], 1))
        if on_pair is not None:
            on_pair(names[2 * k], pos3 + neg3)
    col_bits = np.stack([planes[2 * k][0, :, 0] > 0 for k in range(n_col)])
    row_bits = np.stack([planes[2 * k][:, 0, 0] > 0 for k in range(n_col, n_pairs)])
    ok = lit & reliable.all(axis=0)
    column = _lut_decode(bits[:n_col], col_bits)
    row = _lut_decode(bits[n_col:], row_bits)
    ok &= (column >= 0) & (row >= 0)
    column = np.where(ok, column, -1).astype(np.int32)
    row = np.where(ok, row, -1).astype(np.int32)
    return GrayCode(
        column,
        row,
        lit,
        bits,
        reliable,
        tuple(names),
        n_col,
        col_bits,
        row_bits,
        np.concatenate(samples) if samples else np.zeros((0, 4, 3), np.float32),
    )


def _lut_decode(bits: np.ndarray, table: np.ndarray) -> np.ndarray:
    """Bits (n, Hc, Wc) -> index into the table's columns (-1 for a code no column has)."""
    n, size = table.shape
    weights = (1 << np.arange(n)).astype(np.int64)
    lut = np.full(1 << n, -1, np.int64)
    lut[(table.T.astype(np.int64) * weights).sum(axis=1)] = np.arange(size)
    code = np.tensordot(weights, bits.astype(np.int64), axes=(0, 0))
    return lut[code]


def _check_planes(
    gc: GrayCode,
    caps: _Captures,
    predicted: np.ndarray,
    region: np.ndarray,
) -> dict[str, float]:
    """Each Gray-code plane against the chessboard's prediction of the projector coordinates.

    ``predicted`` (Hc, Wc, 2) projector (u, v) from the chessboard, trusted in ``region``.
    Returns the agreement per plane; raises FitError naming a plane that disagrees.
    """
    w, h = gc.col_bits.shape[1], gc.row_bits.shape[1]
    margin = 0.75
    agreement: dict[str, float] = {}
    for k in range(gc.bits.shape[0]):
        is_col = k < gc.n_col_bits
        table = gc.col_bits[k] if is_col else gc.row_bits[k - gc.n_col_bits]
        coord = predicted[..., 0] if is_col else predicted[..., 1]
        size = w if is_col else h
        sel = region & gc.lit
        c = coord[sel]
        lo = np.clip(np.rint(c - margin), 0, size - 1).astype(np.int64)
        mid = np.clip(np.rint(c), 0, size - 1).astype(np.int64)
        hi = np.clip(np.rint(c + margin), 0, size - 1).astype(np.int64)
        same = (table[lo] == table[mid]) & (table[mid] == table[hi])
        if np.count_nonzero(same) < 50:
            continue
        # an unreliable bit (plane and "inverse" alike) counts against the plane too
        bit = gc.bits[k][sel][same]
        sure = gc.reliable[k][sel][same]
        expected = table[mid][same]
        agree = float(np.mean(sure & (bit == expected)))
        inverted = float(np.mean(sure & (bit != expected)))
        agreement[gc.names[2 * k]] = round(agree, 4)
        if agree < BIT_AGREEMENT:
            a, b = caps.rel(gc.names[2 * k]), caps.rel(gc.names[2 * k + 1])
            what = "column" if is_col else "row"
            if inverted > BIT_AGREEMENT:
                reason = (
                    f"{a} and {b} look swapped (bit {k} of the projector {what}s is inverted "
                    f"on {inverted:.0%} of the pixels)"
                )
            else:
                reason = (
                    f"{a} does not show bit {k} of the projector {what}s where the chessboard "
                    f"says it should (agreement {agree:.0%})"
                )
            raise FitError(
                a,
                f"{reason}: the Gray-code captures are out of order or mislabelled, or the "
                "camera moved after the chessboard; capture them again in the order of "
                "`viewcomp patterns` (graycode_00, graycode_01, ...)",
            )
    return agreement


# ---------------------------------------------------------------------------------------------
# The camera's response, from light's additivity


def response_misfit(codes: np.ndarray, response: Response) -> float:
    """How badly ``response`` linearises complementary captures: RMS of
    (L(P) + L(P') - L(W) - L(B)) / (L(W) - L(B)) over the samples.

    ``codes`` (N, 4, 3) encoded 0..1 values of a Gray-code plane P, its inverse P', white W
    and black B at the same pixels. Light adds: where the optics blur a stripe edge, a camera
    pixel gets a share a of the lit side in P and 1 - a in P', so in linear units
    L(P) + L(P') = L(W) + L(B) for any a. Only the true response makes the sum hold at
    intermediate values.
    """
    lin = response.decode(codes).astype(np.float64)
    span = lin[:, 2] - lin[:, 3]
    ok = span > 0.05
    if not np.any(ok):
        return float("nan")
    err = (lin[:, 0] + lin[:, 1] - lin[:, 2] - lin[:, 3])[ok] / span[ok]
    return float(np.sqrt(np.mean(err**2)))


def estimate_response(codes: np.ndarray) -> tuple[Response, float]:
    """The response among "linear", "srgb" and power laws g in :data:`RESPONSE_GAMMAS` that
    best satisfies additivity (:func:`response_misfit`); returns it and its misfit.

    An estimate for cameras that do nothing non-linear to neighbouring pixels (in-camera
    sharpening or local tone mapping break additivity: switch them off).
    """
    from scipy.optimize import minimize_scalar

    if len(codes) < 100:
        raise ValueError(f"too few stripe-edge samples to estimate a response ({len(codes)})")
    found = minimize_scalar(
        lambda g: response_misfit(codes, parse_response(float(g))),
        bounds=RESPONSE_GAMMAS,
        method="bounded",
        options={"xatol": 1e-3},
    )
    cands = [
        (parse_response("linear"), response_misfit(codes, parse_response("linear"))),
        (parse_response("srgb"), response_misfit(codes, parse_response("srgb"))),
        (parse_response(round(float(found.x), 2)), float(found.fun)),
    ]
    return min(cands, key=lambda c: c[1])


def estimate_set_response(cs: CaptureSet) -> tuple[Response, float]:
    """:func:`estimate_response` from a camera-space set's Gray-code captures (screen/).

    Raises:
        FitError: Gray-code captures missing or the projector not visible.
        ValueError: too few stripe-edge pixels (a blur-free or tiny image).
    """
    caps = _Captures(cs, "screen")
    gc = decode_graycode(caps, cs.rig.projector.resolution)
    return estimate_response(caps.response.encode(gc.response_samples))


def _check_response(gc: GrayCode, response: Response, where: str) -> dict[str, Any]:
    """Compare the rig's response with the best estimate from the Gray-code pairs; refuse a
    rig response that misfits grossly. Returns the statistics."""
    codes = response.encode(gc.response_samples)
    if len(codes) < 100:
        return {"rig": response.spec, "samples": len(codes)}
    rig_misfit = response_misfit(codes, response)
    best, best_misfit = estimate_response(codes)
    out = {
        "rig": response.spec,
        "rig_misfit": round(rig_misfit, 4),
        "estimated": best.spec,
        "estimated_misfit": round(best_misfit, 4),
        "samples": len(codes),
    }
    limit, ratio = RESPONSE_REFUSE
    if rig_misfit > limit and rig_misfit > ratio * best_misfit:
        raise FitError(
            where,
            f"[camera] response = {response.spec!r} does not linearise the captures: "
            f"complementary Gray-code captures do not add up (misfit {rig_misfit:.3f}), while "
            f"response = {best.spec!r} fits ({best_misfit:.3f}); set it in rig.toml, or switch "
            "off the camera's sharpening and tone mapping if it has them",
        )
    return out


# ---------------------------------------------------------------------------------------------
# The dense map


def _fit_map(
    cam_pts: np.ndarray,
    proj_pts: np.ndarray,
    k: np.ndarray,
    dist0: np.ndarray,
    h0: np.ndarray,
    size: tuple[int, int],
) -> tuple[ProjectorMap, dict[str, float]]:
    """Robust least squares of the map's homography and lens (k1, k2, p1, p2), then the cubic
    residual correction, on decoded (camera, projector) pairs (N, 2) each."""
    cu, cv = (size[0] - 1) / 2.0, (size[1] - 1) / 2.0
    s = (proj_pts[:, 0] - cu) / cu
    t = (proj_pts[:, 1] - cv) / cv
    h0 = h0 / h0[2, 2]

    def unpack(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        h = np.append(x[:8], 1.0).reshape(3, 3)
        dist = np.array([x[8], x[9], x[10], x[11], 0.0])
        return h, dist

    def residual(x: np.ndarray) -> np.ndarray:
        h, dist = unpack(x)
        return (_model(k, dist, h, s, t) - cam_pts).ravel()

    x0 = np.concatenate([h0.ravel()[:8], [dist0[0], dist0[1], 0.0, 0.0]])
    sol = least_squares(residual, x0, loss="soft_l1", f_scale=1.0, x_scale="jac", method="trf")
    h, dist = unpack(sol.x)
    r = (cam_pts - _model(k, dist, h, s, t)).reshape(-1, 2)
    err = np.linalg.norm(r, axis=1)
    inl = err < max(3.0, 4.0 * float(np.median(err)))
    basis = _poly_basis(s[inl], t[inl])
    coef, *_ = np.linalg.lstsq(basis, r[inl], rcond=None)
    pmap = ProjectorMap(k, dist, h, coef.T.copy(), size)
    final = np.linalg.norm(cam_pts[inl] - pmap(proj_pts[inl]), axis=1)
    stats = {
        "points": len(cam_pts),
        "inlier_fraction": round(float(inl.mean()), 4),
        "rms_px": round(float(np.sqrt(np.mean(final**2))), 4),
        "rms_before_polynomial_px": round(float(np.sqrt(np.mean(err[inl] ** 2))), 4),
    }
    return pmap, stats


def _predict_from_chessboard(
    corners: Corners, k: np.ndarray, dist: np.ndarray, shape: tuple[int, int]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Projector (u, v) predicted at every camera pixel inside the chessboard's hull, from a
    homography on the undistorted corners. Returns (predicted (Hc, Wc, 2), region (Hc, Wc)
    bool, the homography projector px -> undistorted normalised camera)."""
    und = undistort_pixels(corners.camera, k, dist)
    hom, _ = cv2.findHomography(corners.projector, und)
    region = np.zeros(shape, np.uint8)
    hull = cv2.convexHull(corners.camera.astype(np.float32)).astype(np.int32)
    cv2.fillConvexPoly(region, hull, 1)
    region = cv2.erode(region, np.ones((5, 5), np.uint8)).astype(bool)
    ys, xs = np.nonzero(region)
    pred = np.full((*shape, 2), np.nan)
    if len(xs):
        und_px = undistort_pixels(np.stack([xs, ys], 1).astype(np.float64), k, dist)
        inv = np.linalg.inv(hom)
        u, v = _apply_h(inv, und_px[:, 0], und_px[:, 1])
        pred[ys, xs, 0] = u
        pred[ys, xs, 1] = v
    return pred, region, hom


def edge_image(img: np.ndarray) -> np.ndarray:
    """(Hc, Wc) float32 sharp edges of a linear image (Hc, Wc, 3): the gradient magnitude minus
    its local mean (a ramp's steady slope and smooth shading vanish, the projector frame's and
    the chessboard's edges stay)."""
    g = _gray(img)
    top = float(np.percentile(g, 99.5))
    g = g / max(top, 1e-6)
    gx = cv2.Sobel(g, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(g, cv2.CV_32F, 0, 1, ksize=3)
    e = np.sqrt(gx * gx + gy * gy)
    return np.maximum(e - cv2.GaussianBlur(e, (0, 0), 4.0), 0.0)


def frame_shift(reference: np.ndarray, image: np.ndarray) -> tuple[float, float]:
    """How far (camera px) ``image``'s sharp edges (the projector frame's) have moved from
    ``reference``'s, by phase correlation; both (Hc, Wc, 3) linear, or ``reference`` already
    an edge image (Hc, Wc) of :func:`edge_image`. Returns (shift, peak): ``peak`` in 0..1 says
    how clearly the images match (a capture of a lit pattern against another: > 0.3; below
    :data:`MIN_PEAK` the shift means nothing)."""
    ref = reference if reference.ndim == 2 else edge_image(reference)
    (dx, dy), peak = cv2.phaseCorrelate(ref, edge_image(image))
    return float(np.hypot(dx, dy)), float(peak)


# ---------------------------------------------------------------------------------------------
# Order checks of Table 1 (on the projector grid)


def check_pattern_order(images: Mapping[str, np.ndarray], sub: str) -> None:
    """Refuse Table-1 captures that are not what their names say (wrong order, mislabelled).

    ``images``: name -> (H, W, 3) linear on the projector grid. Checks that gray is brighter
    than black, red/green/blue raise their own camera channel most over gray, and the ramp
    rises from left to right.

    Raises:
        FitError: naming the capture and the fix.
    """
    fix = (
        "the captures are in the wrong order or mislabelled: capture red (130,110,110), green "
        "(110,130,110), blue (110,110,130), gray (110,110,110) and the ramp as `viewcomp "
        "patterns` writes them"
    )
    h, w = images["gray"].shape[:2]
    inner = (slice(h // 10, h - h // 10), slice(w // 10, w - w // 10))
    mean = {
        k: np.asarray(v, np.float64)[inner].reshape(-1, 3).mean(axis=0) for k, v in images.items()
    }
    if "black" in mean and mean["gray"].sum() <= mean["black"].sum():
        raise FitError(f"{sub}/gray", f"is not brighter than {sub}/black: {fix}")
    for c, name in enumerate(("red", "green", "blue")):
        d = mean[name] - mean["gray"]
        if d[c] <= 0 or d[c] <= max(d[(c + 1) % 3], d[(c + 2) % 3]):
            raise FitError(
                f"{sub}/{name}",
                f"does not raise the {name} camera channel most over {sub}/gray (change "
                f"R,G,B = {d[0]:+.4f}, {d[1]:+.4f}, {d[2]:+.4f}): {fix}",
            )
    ramp = np.asarray(images["ramp"], np.float64)[inner[0]].mean(axis=(0, 2))
    cols = np.arange(ramp.size, dtype=np.float64)
    corr = float(np.corrcoef(cols, ramp)[0, 1]) if ramp.std() > 0 else 0.0
    if not corr > 0.9:
        raise FitError(
            f"{sub}/ramp",
            f"does not rise from left to right (correlation with the column {corr:+.2f}): {fix}",
        )


# ---------------------------------------------------------------------------------------------
# The whole step


class _MoveCheck:
    """Captures that show the projector's frame (Table 1 but black, the chessboards, each
    Gray-code plane plus its inverse) against screen/graycode_white: the frame must be visible
    and within :data:`MOVE_LIMIT_PX`. ``worst`` keeps the largest shift (camera px)."""

    def __init__(self, screen: _Captures) -> None:
        self.screen = screen
        ref = screen.get("graycode_white")
        self.black = screen.get("graycode_black")
        self.lit, _ = _lit_mask(_gray(ref), _gray(self.black), screen.rel("graycode_white"))
        self.lit_level = float((ref - self.black)[self.lit].mean())
        self.ref_edges = edge_image(ref)
        self.worst = 0.0
        self.pending: FitError | None = None

    def flush(self, in_view: Callable[[], None]) -> None:
        """Raise a failed match held back (``in_view`` first: the clearer reason)."""
        if self.pending is not None:
            in_view()
            raise self.pending

    def __call__(
        self,
        caps: _Captures,
        name: str,
        img: np.ndarray,
        in_view: Callable[[], None] | None = None,
    ) -> None:
        """Check one capture (Hc, Wc, 3) linear; ``in_view`` raises first when the frame is
        not wholly seen (a clearer reason for a failed match); without it a failed match is
        held back for :meth:`flush`.

        Raises:
            FitError: a capture as dark as black (wrong order, projector off), or whose frame
                has moved (the camera moved between captures) or cannot be matched.
        """
        ref_rel = self.screen.rel("graycode_white")
        level = float((img - self.black)[self.lit].mean()) / max(self.lit_level, 1e-9)
        if level < 0.02:
            raise FitError(
                caps.rel(name),
                f"does not show the projected pattern (where the projector lights, it is "
                f"{level:.1%} as bright as graycode_white, as dark as black): the captures are "
                "in the wrong order or mislabelled, or the projector was off; capture again",
            )
        d, peak = frame_shift(self.ref_edges, img)
        if peak < MIN_PEAK:
            error = FitError(
                caps.rel(name),
                f"the projector's frame cannot be matched with {ref_rel}'s (phase-correlation "
                f"peak {peak:.2f}): the camera moved a lot, the frame is not wholly in view, or "
                "this is not a capture of this rig; fix the camera so that it sees the whole "
                "projected image and capture the set again",
            )
            if in_view is None:  # decide once it is known whether the frame is in view
                self.pending = self.pending or error
                return
            in_view()
            raise error
        if d > MOVE_LIMIT_PX:
            raise FitError(
                caps.rel(name),
                f"the projector's frame lies {d:.1f} camera px from where {ref_rel} has it: the "
                "camera moved between captures; fix the camera (and lock its zoom and focus) "
                "and capture the set again",
            )
        self.worst = max(self.worst, d)


def _check_coverage(gc: GrayCode, size: tuple[int, int], rel: str) -> None:
    """Refuse a Gray code that leaves a part of the projector image undecoded (the map would
    extrapolate there): every cell of a COVERAGE_CELLS grid over the projector image must hold
    decoded camera pixels."""
    w, h = size
    cols, rows = COVERAGE_CELLS
    ok = gc.column >= 0
    cu = np.minimum(gc.column[ok] * cols // w, cols - 1)
    cv = np.minimum(gc.row[ok] * rows // h, rows - 1)
    counts = np.bincount(cv * cols + cu, minlength=cols * rows).reshape(rows, cols)
    empty = np.argwhere(counts == 0)
    if len(empty):
        r, c = empty[0]
        u, v = int((c + 0.5) * w / cols), int((r + 0.5) * h / rows)
        raise FitError(
            rel,
            f"the Gray code is not decoded in {len(empty)} of {cols * rows} parts of the "
            f"projector image (e.g. around projector pixel ({u}, {v})): the camera does not see "
            "that part (out of view, occluded) or the screen is too dark there; make the whole "
            "projected image visible to the camera and capture again",
        )


@dataclass
class Geometry:
    """The geometric calibration of a camera-space set: the ``map`` projector -> camera, the
    chessboard ``corners`` of screen/chessboard, the decoded ``graycode`` and JSON-ready
    ``stats`` (reprojection errors in camera pixels, the lens, the largest frame shift)."""

    map: ProjectorMap
    corners: Corners
    graycode: GrayCode
    stats: dict[str, Any]


def calibrate_geometry(cs: CaptureSet) -> Geometry:
    """Chessboard + Zhang, Gray code, the dense map and the camera-moved checks (steps 1-3 of
    the module doc) for a ``space = "camera"`` capture set.

    Raises:
        FitError: a capture that makes geometric calibration impossible (see module doc).
    """
    t0 = time.perf_counter()
    rig = cs.rig
    size = rig.projector.resolution
    cw, ch = rig.camera.resolution
    shape = (ch, cw)
    screen = _Captures(cs, "screen")
    white = _Captures(cs, "white")

    # 1. chessboard + Zhang
    cb = screen.get("chessboard")
    sat = screen.saturation.get("chessboard", 0.0)
    if sat > SATURATION_LIMIT:
        raise FitError(
            screen.rel("chessboard"),
            f"{sat:.1%} of its pixel-channels are at the maximum code (saturated): lower the "
            "camera's exposure or the projector's brightness and capture again",
        )
    corners = find_corners(cb, size, screen.rel("chessboard"))
    k, dist, zhang_rms = zhang(corners, rig)
    stats: dict[str, Any] = {
        "space": "camera",
        "chessboard": {
            "corners": len(corners.camera),
            "zhang_rms_px": round(zhang_rms, 4),
            "distortion": [round(float(v), 5) for v in dist],
        },
    }
    if white.has("chessboard"):
        wc = find_corners(white.get("chessboard"), size, white.rel("chessboard"))
        shift = float(np.sqrt(np.mean(np.sum((wc.camera - corners.camera) ** 2, axis=1))))
        stats["chessboard"]["white_vs_screen_px"] = round(shift, 4)
        if shift > MOVE_LIMIT_PX:
            raise FitError(
                white.rel("chessboard"),
                f"its corners lie {shift:.1f} camera px (RMS) from those of "
                f"{screen.rel('chessboard')}: the camera (or the screen plane) moved between the "
                "white screen's captures and the real screen's; fix the camera and capture both "
                "sets again",
            )

    # 2. Gray code; the camera must not have moved; each plane checked against the chessboard
    mover = _MoveCheck(screen)
    gc = decode_graycode(screen, size, on_pair=lambda n, img: mover(screen, n, img))
    stats["response"] = _check_response(gc, screen.response, "rig.toml")
    gc_rel = screen.rel(gc.names[0])
    mover.flush(lambda: _check_coverage(gc, size, gc_rel))
    for caps in (white, screen):
        for n in (*REQUIRED, *OPTIONAL, "chessboard"):
            if n != "black" and caps.has(n):
                mover(caps, n, caps.get(n), lambda: _check_coverage(gc, size, gc_rel))
    stats["max_frame_shift_px"] = round(mover.worst, 4)
    pred, region, h_cb = _predict_from_chessboard(corners, k, dist, shape)
    agreement = _check_planes(gc, screen, pred, region)
    _check_coverage(gc, size, screen.rel(gc.names[0]))
    ok = gc.column >= 0
    lit_frac = float(ok.sum()) / max(int(gc.lit.sum()), 1)
    if lit_frac < MIN_DECODED:
        raise FitError(
            screen.rel(gc.names[0]),
            f"only {lit_frac:.0%} of the lit camera pixels decode to a projector pixel: the "
            "Gray-code captures are blurred, too dark or out of order; focus the camera, check "
            "the exposure and capture them again",
        )

    # 3. the dense map
    ys, xs = np.nonzero(ok)
    step = max(1, int(np.ceil(len(xs) / MAX_DENSE_POINTS)))
    sel = slice(None, None, step)
    cam_pts = np.stack([xs[sel], ys[sel]], 1).astype(np.float64)
    proj_pts = np.stack([gc.column[ys[sel], xs[sel]], gc.row[ys[sel], xs[sel]]], 1).astype(
        np.float64
    )
    cu, cv = (size[0] - 1) / 2.0, (size[1] - 1) / 2.0
    norm = np.array([[1 / cu, 0, -1], [0, 1 / cv, -1], [0, 0, 1]])
    h0 = h_cb @ np.linalg.inv(norm)
    pmap, fit = _fit_map(cam_pts, proj_pts, k, dist, h0, size)
    corner_err = np.linalg.norm(pmap(corners.projector) - corners.camera, axis=1)
    corner_rms = float(np.sqrt(np.mean(corner_err**2)))
    stats["graycode"] = {
        "decoded_fraction_of_lit": round(lit_frac, 4),
        "plane_agreement_min": min(agreement.values()) if agreement else None,
        **fit,
    }
    stats["map"] = {
        "model": "camera = K dist(H [s, t, 1]) + cubic(s, t)",
        "distortion": [round(float(v), 5) for v in pmap.distortion],
        "chessboard_rms_px": round(corner_rms, 4),
    }
    if corner_rms > MOVE_LIMIT_PX:
        raise FitError(
            screen.rel(gc.names[0]),
            f"the Gray-code map misses the chessboard's corners by {corner_rms:.1f} camera px "
            f"(RMS): the camera moved between {screen.rel('chessboard')} and the Gray-code "
            "captures; fix the camera and capture the set again",
        )
    mx, my = pmap.grid()
    outside = (mx < -0.5) | (mx > cw - 0.5) | (my < -0.5) | (my > ch - 0.5)
    if outside.any():
        raise FitError(
            screen.rel("graycode_white"),
            f"{outside.mean():.1%} of the projector's pixels fall outside the camera's image: "
            "aim or zoom the camera out so that it sees the whole projected image, with a margin",
        )

    stats["seconds"] = round(time.perf_counter() - t0, 2)
    return Geometry(pmap, corners, gc, stats)


def rectify_capture_set(cs: CaptureSet) -> tuple[CaptureSet, dict[str, Any]]:
    """Rectify a ``space = "camera"`` capture set onto the projector grid.

    Returns a CaptureSet whose ``white`` and ``screen`` hold the Table-1 captures (and black)
    as float32 (H, W, 3) linear on the projector grid, with saturation fractions measured on
    the projector grid (the rig is unchanged); and the geometric statistics of
    :func:`calibrate_geometry`.

    Raises:
        FitError: a capture that makes geometric calibration or rectification impossible.
    """
    t0 = time.perf_counter()
    geo = calibrate_geometry(cs)
    stats = dict(geo.stats)
    maps = geo.map.grid()
    white, screen = _Captures(cs, "white"), _Captures(cs, "screen")
    rect: dict[str, dict[str, np.ndarray]] = {"white": {}, "screen": {}}
    fractions: dict[tuple[str, str], float] = {}
    for caps in (white, screen):
        for n in (*REQUIRED, *OPTIONAL):
            if n not in caps.memory:
                continue
            img = caps.get(n)
            rect[caps.sub][n] = fill_border(rectify(img, maps), BORDER_PX)
            top = (img >= 1.0).astype(np.float32)
            fractions[(caps.sub, n)] = float(rectify(top, maps).round().mean())
        check_pattern_order(rect[caps.sub], caps.sub)
    stats["seconds"] = round(time.perf_counter() - t0, 2)
    out = CaptureSet(
        rig=cs.rig,
        white=rect["white"],
        screen=rect["screen"],
        raw_max_fraction=fractions,
        path=cs.path,
        extra={},
    )
    return out, stats
