"""Lens distortion: OpenCV's model (k1, k2, p1, p2, k3) on normalised image coordinates.

The one place the formula lives: the rig's devices project and cast rays through it, the
geometric calibration fits it. Normalised coordinates are x_n = (u - cx) / f and
y_n = (v - cy) / f (pixels, x right, y down, pixel centres at integers).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

Distortion = Sequence[float] | np.ndarray  # (k1, k2, p1, p2, k3), OpenCV order


def distort_normalised(
    xn: np.ndarray, yn: np.ndarray, dist: Distortion
) -> tuple[np.ndarray, np.ndarray]:
    """Undistorted -> distorted normalised coordinates (arrays of any one shape)."""
    k1, k2, p1, p2, k3 = (float(v) for v in dist)
    r2 = xn * xn + yn * yn
    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    xd = xn * radial + 2.0 * p1 * xn * yn + p2 * (r2 + 2.0 * xn * xn)
    yd = yn * radial + p1 * (r2 + 2.0 * yn * yn) + 2.0 * p2 * xn * yn
    return xd, yd


def undistort_normalised(
    xd: np.ndarray, yd: np.ndarray, dist: Distortion, iterations: int = 50
) -> tuple[np.ndarray, np.ndarray]:
    """The inverse of :func:`distort_normalised` by fixed-point iteration (exact to float
    precision for the mild lenses of cameras and projectors, |k1| well below 1)."""
    xn, yn = np.array(xd, np.float64), np.array(yd, np.float64)
    for _ in range(iterations):
        fx, fy = distort_normalised(xn, yn, dist)
        xn = xn - (fx - xd)
        yn = yn - (fy - yd)
    return xn, yn
