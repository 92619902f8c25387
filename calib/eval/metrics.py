"""Image error measures for the evaluation (docs/MODEL.md section 5).

Every function compares two 8-bit *encoded* RGB images (H, W, 3) uint8, 0..255, of one size:
in the evaluation, ``a`` is a result seen from the eye (T_o, T_90, T_theta, ...) and ``b`` is
the ideal T_i (the test image projected on the matte white screen, seen from the same eye).
Both are what the camera / eye records after its response, not linear light.
"""

from __future__ import annotations

import math

import numpy as np
from skimage.color import deltaE_ciede2000, rgb2lab
from skimage.metrics import structural_similarity


def _check(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    a = np.asarray(a)
    b = np.asarray(b)
    for name, x in (("a", a), ("b", b)):
        if x.dtype != np.uint8 or x.ndim != 3 or x.shape[2] != 3:
            raise ValueError(
                f"{name} must be an 8-bit encoded RGB image (H, W, 3) uint8, "
                f"got {x.dtype} {x.shape}"
            )
    if a.shape != b.shape:
        raise ValueError(f"images differ in size: a is {a.shape}, b is {b.shape}")
    return a, b


def sse(a: np.ndarray, b: np.ndarray) -> float:
    """Eq. 26: E = sum over all pixels and the 3 channels of (a - b)^2, in 8-bit units
    squared (levels^2), as float64. 0 for identical images; at most 255^2 * H * W * 3."""
    a, b = _check(a, b)
    d = a.astype(np.float64) - b.astype(np.float64)
    return float(np.sum(d * d))


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    """Peak signal-to-noise ratio in dB with peak 255: 10 log10(255^2 / MSE), MSE = SSE / (H W 3)
    in 8-bit units. ``inf`` for identical images; higher is better."""
    a, b = _check(a, b)
    mse = sse(a, b) / a.size
    if mse == 0.0:
        return math.inf
    return 10.0 * math.log10(255.0**2 / mse)


def ssim(a: np.ndarray, b: np.ndarray) -> float:
    """Mean structural similarity (skimage, 7x7 window, data_range = 255, computed per channel
    and averaged), -1..1, 1 for identical images. Needs H, W >= 7."""
    a, b = _check(a, b)
    if min(a.shape[:2]) < 7:
        raise ValueError(f"ssim needs images of at least 7x7 pixels, got {a.shape[1]}x{a.shape[0]}")
    return float(structural_similarity(a, b, channel_axis=-1, data_range=255))


def delta_e2000(a: np.ndarray, b: np.ndarray) -> float:
    """Mean CIEDE2000 colour difference over all pixels, in dE units (about 1 = just
    noticeable; black vs white = 100). Both images are taken as sRGB-encoded (D65): value/255
    through ``skimage.color.rgb2lab``, then ``deltaE_ciede2000`` per pixel."""
    a, b = _check(a, b)
    lab_a = rgb2lab(a.astype(np.float64) / 255.0)
    lab_b = rgb2lab(b.astype(np.float64) / 255.0)
    return float(np.mean(deltaE_ciede2000(lab_a, lab_b)))
