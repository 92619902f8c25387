"""The *adapted* colour error: mean CIEDE2000 after the best uniform brightness scale.

A viewer's eye adapts to the overall level of what it looks at (within about two stops), so
a picture that is uniformly dimmer than the ideal but right in colour and contrast looks
right; today's mean CIEDE2000 (:func:`~viewcomp.calib.eval.metrics.delta_e2000`) counts the
dimming at every pixel. The adapted error takes the seen image's linear light (the sRGB
decoding of its 8-bit values, the convention the CIEDE2000 measure itself uses), scales it
by s, clips it to [0, 1], encodes it again (sRGB, not re-quantised) and keeps the smallest
mean CIEDE2000 to the ideal over s in [1/4, 4]:

    adapted(seen, ideal) = min over s in [SCALE_MIN, SCALE_MAX] of
                           mean_x dE00(encode(clip(s decode(seen))), ideal)

The search: s on a grid of quarter stops (log2 s from -2 to 2), measured on every
``SEARCH_STEP``-th pixel of each axis, then a bounded scalar minimisation around the best
grid point (``scipy.optimize.minimize_scalar``), and the chosen s measured on every pixel.
s = 1 is on the grid, so the adapted error is at most the plain one (up to the float
rounding of a decode/encode round trip).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize_scalar
from skimage.color import deltaE_ciede2000, rgb2lab

from viewcomp.calib.world.response import Response

#: The eye's adaptation range: s in [SCALE_MIN, SCALE_MAX] (two stops either way).
SCALE_MIN = 0.25
SCALE_MAX = 4.0
#: The grid's step in stops (log2 s).
GRID_STOPS = 0.25
#: The search measures every SEARCH_STEP-th row and column (the chosen s is then measured on
#: every pixel).
SEARCH_STEP = 2

SRGB = Response("srgb")


@dataclass(frozen=True)
class Adapted:
    """An adapted error: ``de`` mean CIEDE2000 at the best ``scale`` (linear light)."""

    de: float
    scale: float


def encoded_lab(encoded01: np.ndarray) -> np.ndarray:
    """CIELAB (..., 3) of sRGB-encoded values 0..1 (float), as
    :func:`~viewcomp.calib.eval.metrics.delta_e2000` converts 8-bit images (``rgb2lab``)."""
    return rgb2lab(np.asarray(encoded01, np.float64))


def scaled_lab(linear: np.ndarray, s: float) -> np.ndarray:
    """CIELAB of linear light (..., 3) scaled by ``s``, clipped to [0, 1], sRGB-encoded."""
    return encoded_lab(SRGB.encode(np.clip(s * linear, 0.0, 1.0)))


def best_scale(
    error: Callable[[float], float], lo: float = SCALE_MIN, hi: float = SCALE_MAX
) -> float:
    """The s in [lo, hi] minimising ``error(s)``: a quarter-stop grid, then a bounded scalar
    search within a quarter stop of the best grid point."""
    f = error
    stops = np.arange(np.log2(lo), np.log2(hi) + 1e-9, GRID_STOPS)
    vals = [float(f(float(2.0**t))) for t in stops]
    k = int(np.argmin(vals))
    a = max(float(stops[k]) - GRID_STOPS, float(np.log2(lo)))
    b = min(float(stops[k]) + GRID_STOPS, float(np.log2(hi)))
    res = minimize_scalar(
        lambda t: float(f(float(2.0**t))),
        bounds=(a, b),
        method="bounded",
        options={"xatol": 0.01},
    )
    return float(2.0**res.x) if float(res.fun) < vals[k] else float(2.0 ** stops[k])


def adapted_delta_e(seen: np.ndarray, ideal: np.ndarray) -> Adapted:
    """The adapted mean CIEDE2000 of ``seen`` against ``ideal`` (module docstring).

    Args:
        seen, ideal: (H, W, 3) uint8, sRGB-encoded images of one size (what the eye sees of a
            result, and of the test image on the white screen).

    Returns:
        :class:`Adapted`: the error (dE units) and the scale s in [1/4, 4] that gives it.
    """
    for name, x in (("seen", seen), ("ideal", ideal)):
        if x.dtype != np.uint8 or x.ndim != 3 or x.shape[2] != 3:
            raise ValueError(f"{name} must be (H, W, 3) uint8, got {x.dtype} {x.shape}")
    if seen.shape != ideal.shape:
        raise ValueError(f"images differ in size: {seen.shape} and {ideal.shape}")
    linear = SRGB.decode(seen.astype(np.float64) / 255.0).astype(np.float64)
    goal = encoded_lab(ideal.astype(np.float64) / 255.0)
    sub = (slice(None, None, SEARCH_STEP), slice(None, None, SEARCH_STEP))
    lin_s, goal_s = linear[sub], goal[sub]

    def search(s: float) -> float:
        return float(np.mean(deltaE_ciede2000(scaled_lab(lin_s, s), goal_s)))

    s = best_scale(search)
    return Adapted(float(np.mean(deltaE_ciede2000(scaled_lab(linear, s), goal))), s)
