"""The tone map C_c = alpha C_w + beta (Eqs. 21, 22) and how it is chosen.

(alpha, beta) = argmin  E_u + E_l + lambda (1 - alpha)^2  [+ mu (beta / C_mean)^2]

Normalisation (the paper leaves it open; this is our choice): E_u and E_l are the *fractions*
of pixel-channels (0..1) whose value, after the tone map, lands above the upper or below the
lower bound of what the real screen can show. lambda then reads "how many percent of
clipped pixel-channels one is willing to trade for (1 - alpha)^2 of brightness"; the default
lambda = 1 accepts alpha = 0.9 to save 1 % clipping. Among the betas that reach the same
minimum, the one closest to 0 is taken (the least change of black level).

The bracketed black-lift term is ours, not the paper's: a count of clipped pixel-channels
says nothing of how far they are off, so with mu = 0 a few unreachable pixel-channels make
the optimum lift the black level of the whole image (beta > 0), which costs far more than it
saves. mu (beta / C_mean)^2, with C_mean the image's mean white-screen level, prices a lift
of the black level relative to the image's mean: with the default mu = 3, lifting it by 10 %
of the mean costs as much as clipping 3 % of the pixel-channels. The paper's method uses
mu = 0 (Eq. 22 exactly); the per-pixel method and the oracle use mu = 3. The evaluation's
trade-off plot shows both.

Every method (paper, per pixel, oracle) reduces to the same form per pixel-channel:
``y = alpha * u + beta * v + c`` must lie in ``[lo, hi]``, so one exact solver serves all:
for each alpha on a grid, the set of betas that keeps a pixel-channel in range is an
interval, and the beta covered by the most intervals is found by a sweep.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

DEFAULT_LAMBDA = 1.0
DEFAULT_BETA_WEIGHT = 3.0
ALPHA_STEP = 0.01
ALPHA_MIN = 0.1


@dataclass(frozen=True)
class ToneMap:
    """A chosen tone map and what it costs: ``clipped`` is E_u + E_l as a fraction."""

    alpha: float
    beta: float
    clipped: float
    cost: float


def _coverage(lo_b: np.ndarray, hi_b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Candidate betas and how many closed intervals [lo_b, hi_b] hold each.

    The count is piecewise constant in beta, so the optimum of (count + a penalty growing
    with |beta|) lies at 0 or at an interval end: those are the candidates.
    """
    starts = np.sort(lo_b)
    ends = np.sort(hi_b)
    cand = np.concatenate([[0.0], starts, ends])
    inside = np.searchsorted(starts, cand, "right") - np.searchsorted(ends, cand, "left")
    return cand, inside


def choose_tone_map(
    u: np.ndarray,
    v: np.ndarray,
    c: np.ndarray,
    lo: np.ndarray | float,
    hi: np.ndarray | float,
    lam: float = DEFAULT_LAMBDA,
    beta_weight: float = 0.0,
    beta_scale: float = 1.0,
) -> ToneMap:
    """Solve Eq. 22 exactly on an alpha grid (step 0.01) for ``y = alpha u + beta v + c``.

    Args:
        u, v, c: (..., 3) per pixel-channel coefficients (any units, the bounds' units).
        lo, hi: bounds, broadcastable to ``u``.
        lam: lambda >= 0, the weight of the brightness penalty (1 - alpha)^2.
        beta_weight: mu >= 0, weight of the black-lift penalty mu (beta / beta_scale)^2; 0 is
            the paper's Eq. 22 exactly (ties still go to the beta closest to 0).
        beta_scale: the level beta is compared with (the image's mean white-screen level).

    Alpha is searched on a 0.05 grid from 1 down to 0.1, then on a 0.01 grid around the best.

    Returns:
        The ToneMap minimising E_u + E_l + lam (1 - alpha)^2 + mu (beta / scale)^2 (largest
        alpha among ties).
    """
    if lam < 0:
        raise ValueError(f"lambda must be >= 0, got {lam}")
    u = np.asarray(u, np.float64)
    v = np.broadcast_to(np.asarray(v, np.float64), u.shape).ravel()
    c = np.broadcast_to(np.asarray(c, np.float64), u.shape).ravel()
    lo_a = np.broadcast_to(np.asarray(lo, np.float64), u.shape).ravel()
    hi_a = np.broadcast_to(np.asarray(hi, np.float64), u.shape).ravel()
    u = u.ravel()
    total = u.size
    if total == 0:
        return ToneMap(1.0, 0.0, 0.0, 0.0)
    eps = 1e-12
    pos, neg = v > eps, v < -eps
    var = pos | neg

    def at(a: float) -> ToneMap:
        y0 = a * u + c
        fixed_in = int(np.count_nonzero(~var & (y0 >= lo_a) & (y0 <= hi_a)))
        vv = v[var]
        b1 = (lo_a[var] - y0[var]) / vv
        b2 = (hi_a[var] - y0[var]) / vv
        cand, inside = _coverage(np.minimum(b1, b2), np.maximum(b1, b2))
        clipped = 1.0 - (inside + fixed_in) / total
        cost = clipped + lam * (1.0 - a) ** 2 + beta_weight * (cand / beta_scale) ** 2
        # Smallest cost; among equal costs the beta closest to 0.
        k = int(np.lexsort((np.abs(cand), np.round(cost, 12)))[0])
        return ToneMap(float(a), float(cand[k]), float(clipped[k]), float(cost[k]))

    best: ToneMap | None = None
    coarse = np.round(np.arange(1.0, ALPHA_MIN - 1e-9, -0.05), 2)
    for a in coarse:
        t = at(float(a))
        if best is None or t.cost < best.cost - 1e-12:
            best = t
    if best is not None:
        centre = best.alpha
        fine = np.round(np.arange(centre + 0.04, centre - 0.0401, -ALPHA_STEP), 2)
        for a in fine[(fine <= 1.0) & (fine >= ALPHA_MIN)]:
            t = at(float(a))
            if t.cost < best.cost - 1e-12 or (
                abs(t.cost - best.cost) <= 1e-12 and t.alpha > best.alpha
            ):
                best = t
    return best if best is not None else ToneMap(1.0, 0.0, 0.0, 0.0)


class ToneSmoother:
    """Exponential smoothing of (alpha, beta) over video frames, so brightness never flickers.

    ``tau`` is the time constant in seconds; a scene cut is not detected on purpose: the
    picture eases into the new tone map over about ``3 tau``.
    """

    def __init__(self, tau: float = 0.5) -> None:
        self.tau = float(tau)
        self.state: tuple[float, float] | None = None
        self.t: float | None = None

    def update(self, t: float, alpha: float, beta: float) -> tuple[float, float]:
        """Feed the tone map chosen for the frame at time ``t`` (s); returns the smoothed one."""
        if self.state is None or self.t is None or self.tau <= 0:
            self.state, self.t = (alpha, beta), t
            return self.state
        dt = max(t - self.t, 0.0)
        k = 1.0 - float(np.exp(-dt / self.tau))
        a0, b0 = self.state
        self.state = (a0 + k * (alpha - a0), b0 + k * (beta - b0))
        self.t = t
        return self.state
