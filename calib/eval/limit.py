"""The per-pixel physical limit under the adapted error (:mod:`~viewcomp.calib.eval.adapted`).

What no compensation of one frame can beat on a screen seen from one eye, whatever its tone
map: per pixel the best projector light l in the projector's range [lo, hi]^3 (the drive in
[0, 1]^3 through the projector's response), with the one brightness scale s in [1/4, 4] of the
adapted error that suits the whole image best:

    limit = min over s of mean_x min over l(x) of dE00(encode(clip(s seen(l))), ideal)

with seen(l) = M(x) l + A(x) the eye's linear signal (the simulator's true model, clipped and
taken through the eye's response, not quantised) read in linear light as the adapted error
reads an image. The inner minimum is searched per pixel: from the exact inverse clipped into
the range, a coordinate search (each channel moved by +-1 and +-2 steps, the steps shrinking
from a quarter of the range to 1/200 of it). It is a search, not a proof: the figure is an
upper bound of the true limit, found to lie at or below every method measured (the tests and
the reports compare them).
"""

from __future__ import annotations

import numpy as np
from skimage.color import deltaE_ciede2000

from viewcomp.calib.eval.adapted import SRGB, Adapted, best_scale, encoded_lab, scaled_lab
from viewcomp.calib.world.response import Response

#: The coordinate search's steps, as fractions of each channel's range.
STEPS = (0.25, 0.1, 0.04, 0.015, 0.005)
#: Pixels measured: every LIMIT_STEP-th row and column (the limit is a mean over pixels).
LIMIT_STEP = 2
#: The scale's search measures every SEARCH_STEP-th row and column of those.
SEARCH_STEP = 2


class _Screen:
    """One screen at one eye on a subsampled grid: what the eye's linear light is for a light
    (n, 3), in the adapted error's linear convention."""

    def __init__(self, mix: np.ndarray, amb: np.ndarray, response: Response) -> None:
        self.mix, self.amb, self.response = mix, amb, response

    def linear(self, light: np.ndarray) -> np.ndarray:
        sig = np.einsum("nij,nj->ni", self.mix, light) + self.amb
        enc = self.response.encode(np.clip(sig, 0.0, 1.0))
        return SRGB.decode(enc).astype(np.float64)


def _best_light(
    screen: _Screen,
    lo: np.ndarray,
    hi: np.ndarray,
    goal_lin: np.ndarray,
    goal_lab: np.ndarray,
    s: float,
) -> np.ndarray:
    """Per pixel (n,) the smallest CIEDE2000 found at scale ``s`` (module docstring)."""
    target = goal_lin / s - screen.amb
    light = np.clip(np.linalg.solve(screen.mix, target[..., None])[..., 0], lo, hi)

    def err(x: np.ndarray) -> np.ndarray:
        return np.asarray(deltaE_ciede2000(scaled_lab(screen.linear(x), s), goal_lab))

    best = err(light)
    span = hi - lo
    for frac in STEPS:
        for c in range(3):
            base = light[:, c].copy()
            for k in (-2.0, -1.0, 1.0, 2.0):
                cand = light.copy()
                cand[:, c] = np.clip(base + k * frac * span[c], lo[c], hi[c])
                e = err(cand)
                better = e < best
                light[better] = cand[better]
                best = np.where(better, e, best)
    return best


def physical_limit(
    mix: np.ndarray,
    ambient: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    ideal: np.ndarray,
    response: Response,
    step: int = LIMIT_STEP,
) -> Adapted:
    """The per-pixel physical limit (module docstring) of one screen seen from one eye.

    Args:
        mix: (H, W, 3, 3) M(x), the eye's linear signal per unit of projector light.
        ambient: (H, W, 3) A(x), the eye's linear signal with the projector dark (room light).
        lo, hi: (3,) the projector's light at drive 0 and 1 (f(0), f(255)).
        ideal: (H, W, 3) uint8, the test image on the white screen as the eye records it.
        response: the eye's response (linear signal -> encoded values).
        step: measure every ``step``-th row and column.

    Returns:
        :class:`~viewcomp.calib.eval.adapted.Adapted`: the limit (mean dE units) and its s.
    """
    sub = (slice(None, None, step), slice(None, None, step))
    m = np.asarray(mix, np.float64)[sub].reshape(-1, 3, 3)
    a = np.asarray(ambient, np.float64)[sub].reshape(-1, 3)
    enc = ideal[sub].reshape(-1, 3).astype(np.float64) / 255.0
    lo_a, hi_a = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    goal_lin = response.decode(enc).astype(np.float64)
    goal_lab = encoded_lab(enc)
    few = slice(None, None, SEARCH_STEP * SEARCH_STEP)  # every 2nd row and column, roughly
    small = _Screen(m[few], a[few], response)

    def search(s: float) -> float:
        return float(np.mean(_best_light(small, lo_a, hi_a, goal_lin[few], goal_lab[few], s)))

    s = best_scale(search)
    full = _Screen(m, a, response)
    return Adapted(float(np.mean(_best_light(full, lo_a, hi_a, goal_lin, goal_lab, s))), s)
