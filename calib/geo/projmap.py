"""The map from projector pixels to camera pixels, and rectification through it.

camera = K dist(H [s, t, 1]) + r(s, t), with (s, t) the projector pixel scaled to -1..1, K the
camera matrix, dist OpenCV's lens (:mod:`viewcomp.calib.world.lens`), H a homography (exact for
a pinhole projector on a plane) and r a cubic polynomial correction (what the projector's own
lens adds). Fitted by robust least squares to decoded Gray-code pixels, started from Zhang's
lens and the chessboard's homography.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.optimize import least_squares

from viewcomp.calib.geo.chessboard import Corners, undistort_pixels
from viewcomp.calib.world.lens import distort_normalised

POLY_ORDER = 3


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


def rectify(
    image: np.ndarray, maps: tuple[np.ndarray, np.ndarray], sigma: float = 0.0
) -> np.ndarray:
    """Resample a camera image (Hc, Wc, C) onto the projector grid: (H, W, C) float32 (bilinear;
    points outside the camera image take the nearest edge value), after a Gaussian of
    ``sigma`` camera px when > 0 (:func:`reconstruction_sigma`)."""
    img = np.ascontiguousarray(image, np.float32)
    if sigma > 0:
        img = np.asarray(
            cv2.GaussianBlur(img, (0, 0), sigma, borderType=cv2.BORDER_REPLICATE), np.float32
        )
    return cv2.remap(img, maps[0], maps[1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)


def camera_density(maps: tuple[np.ndarray, np.ndarray]) -> float:
    """Camera pixels per projector pixel (along a side; > 0) of ``cv2.remap`` maps (H, W)
    each: the median over the grid of the square root of the map's Jacobian determinant."""
    mx, my = (np.asarray(m, np.float64) for m in maps)
    if mx.shape[0] < 2 or mx.shape[1] < 2:
        raise ValueError(f"maps of shape {mx.shape} have no pixel neighbours")
    xu, yu = np.diff(mx, axis=1)[:-1], np.diff(my, axis=1)[:-1]
    xv, yv = np.diff(mx, axis=0)[:, :-1], np.diff(my, axis=0)[:, :-1]
    return float(np.sqrt(np.median(np.abs(xu * yv - xv * yu))))


#: The reconstruction filter (camera px) of a camera coarser than the projector.
RECONSTRUCTION_SIGMA = 1.0


def reconstruction_sigma(density: float) -> float:
    """The Gaussian (camera px) a camera image gets before it is sampled on the projector
    grid, for ``density`` camera px per projector px.

    A camera at least as fine as the projector: none (each projector pixel is sampled as it
    was). A coarser one (density < 1): :data:`RECONSTRUCTION_SIGMA`. Bilinear interpolation
    alone spreads each camera pixel's own error - an MJPEG block edge, a demosaicking zipper,
    a sharpening overshoot, noise - over 1 / density projector pixels, where every per-pixel
    term of the model takes it as the screen's; the Gaussian averages it with its
    neighbours. It also blurs what the camera resolves: a screen's texture of a period of 8
    camera pixels keeps 73 % of its contrast, of 4 camera pixels 29 %.
    """
    return RECONSTRUCTION_SIGMA if density < 1.0 else 0.0


def fit_map(
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


def predict_from_chessboard(
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
