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


BETA_LIMIT = 100.0  # |beta| beyond this (linear camera units, full scale 1) is never useful


def _window_candidates(
    starts: np.ndarray, ends: np.ndarray, at_zero: int, w: float
) -> tuple[np.ndarray, np.ndarray]:
    """For :func:`_best_per_alpha`: the candidate betas (0, then the interval starts and ends
    within [-w, w], from the sorted runs ``starts`` and ``ends``) and how many intervals hold
    each (``at_zero`` of them hold 0)."""
    k0, k1 = np.searchsorted(starts, -w, "left"), np.searchsorted(starts, w, "right")
    e0, e1 = np.searchsorted(ends, -w, "left"), np.searchsorted(ends, w, "right")
    sw, ew = starts[k0:k1], ends[e0:e1]
    ms = sw.size
    # Intervals holding beta = #starts <= beta - #ends < beta. At the k-th start this is
    # k + 1 - #ends < start (exact at the last of equal starts, lower at the others,
    # which therefore never win); at the k-th end, #starts <= end - k (exact at the
    # first of equal ends). Both counts come from where each lands when the two sorted
    # runs are merged, starts first among equals (a stable sort of the two runs is one
    # merge): the k-th start at position j has j - k ends < it before it; the k-th end
    # at position j has j - k starts <= it before it. In the window, k and j count from
    # its lower edge; the k0 starts and e0 ends below it come first.
    cand = np.concatenate([np.zeros(1), sw, ew])
    pos = np.empty(cand.size - 1, np.intp)
    pos[np.argsort(cand[1:], kind="stable")] = np.arange(pos.size)
    rank2 = 2 * np.arange(max(ms, ew.size))
    inside = np.empty(cand.size, np.intp)
    inside[0] = at_zero
    inside[1 : ms + 1] = (k0 - e0 + 1) + rank2[:ms] - pos[:ms]
    inside[ms + 1 :] = (k0 - e0) + pos[ms:] - rank2[: ew.size]
    return cand, inside


def _best_per_alpha(
    alphas: np.ndarray,
    u: np.ndarray,
    v: np.ndarray,
    c: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    lam: float,
    mu: float,
    scale: float,
    bound: float = np.inf,
) -> list[ToneMap]:
    """The best beta for each alpha (descending), stopping where no alpha can win any more.

    Every cost is at least lam (1 - alpha)^2, which grows as alpha falls: once that exceeds
    the best cost found so far (or ``bound``, the best of an earlier call), the remaining
    alphas are skipped - exactly, they could not be chosen.

    For each alpha, the set of betas keeping a pixel-channel in range is a closed interval;
    how many intervals hold beta is piecewise constant, so the optimum of that count plus a
    penalty growing with |beta| lies at 0 or at an interval's end: those are the candidates.
    With mu > 0 only the candidates whose penalty stays within the cost of beta = 0 can win;
    the counts are made for those alone (a window of the sorted runs; the same choices,
    about half the time). One alpha at a time: arrays of one thumbnail's size stay in cache
    (a (alphas x pixel-channels) block at once was ~3x slower).
    """
    var = np.abs(v) > 1e-12
    all_var = bool(var.all())
    u_v, c_v, lo_v, hi_v = (a if all_var else a[var] for a in (u, c, lo, hi))
    vv = v if all_var else v[var]
    m = vv.size
    # The interval of pixel-channel i is [min(b_lo, b_hi), max(b_lo, b_hi)] with
    # b = (bound - y0) / v: which bound gives its start depends on the sign of v alone, so
    # the start is (bound_s - y0) / v with bound_s chosen once - the very same floats.
    low, high = np.minimum(lo_v, hi_v), np.maximum(lo_v, hi_v)
    bound_s, bound_e = np.where(vv > 0, low, high), np.where(vv > 0, high, low)
    u_f, c_f, lo_f, hi_f = (a[~var] for a in (u, c, lo, hi))
    y0, starts, ends = np.empty(m), np.empty(m), np.empty(m)
    total = u.size
    out: list[ToneMap] = []
    for alpha in alphas:
        alpha = float(alpha)
        penalty = lam * (1.0 - alpha) ** 2
        if penalty > bound + 1e-9:
            break
        fixed_in = 0
        if not all_var:
            y_fixed = alpha * u_f + c_f
            fixed_in = int(np.count_nonzero((y_fixed >= lo_f) & (y_fixed <= hi_f)))
        np.multiply(u_v, alpha, out=y0)
        y0 += c_v
        for run, bnd in ((starts, bound_s), (ends, bound_e)):
            np.subtract(bnd, y0, out=run)
            run /= vv
            run.sort()
            # Clipping is increasing: on a sorted run it keeps it sorted.
            if m and (run[0] < -BETA_LIMIT or run[-1] > BETA_LIMIT):
                np.clip(run, -BETA_LIMIT, BETA_LIMIT, out=run)
        at_zero = np.searchsorted(starts, 0.0, "right") - np.searchsorted(ends, 0.0, "left")
        clipped0 = 1.0 - (at_zero + fixed_in) / total
        # Only betas whose penalty mu (beta / scale)^2 stays within the cost of beta = 0 can
        # win (or tie) against it: the window [-w, w] of the sorted runs, found by bisection.
        w = scale * np.sqrt((clipped0 + penalty + 1e-9) / mu) if mu > 0 else np.inf
        cand, inside = _window_candidates(starts, ends, int(at_zero), w)
        clipped = 1.0 - (inside + fixed_in) / total
        cost = clipped + penalty + mu * (cand / scale) ** 2
        # Smallest cost; among equal costs the beta closest to 0.
        ties = cost <= cost.min() + 1e-12
        k = int(np.argmin(np.where(ties, np.abs(cand), np.inf)))
        out.append(ToneMap(alpha, float(cand[k]), float(clipped[k]), float(cost[k])))
        bound = min(bound, float(cost[k]))
    return out


def choose_tone_map(
    u: np.ndarray,
    v: np.ndarray,
    c: np.ndarray | float,
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

    def pick(alphas: np.ndarray, bound: float = np.inf) -> list[ToneMap]:
        return _best_per_alpha(alphas, u, v, c, lo_a, hi_a, lam, beta_weight, beta_scale, bound)

    def rank(t: ToneMap) -> tuple[float, float]:
        # Smallest cost; among equal costs the largest alpha.
        return (round(t.cost, 12), -t.alpha)

    coarse = np.round(np.arange(1.0, ALPHA_MIN - 1e-9, -0.05), 2)
    best = min(pick(coarse), key=rank)
    fine = np.round(np.arange(best.alpha + 0.04, best.alpha - 0.0401, -ALPHA_STEP), 2)
    fine = fine[(fine <= 1.0) & (fine >= ALPHA_MIN) & (fine != best.alpha)]
    return min([best, *pick(fine, best.cost)], key=rank)


#: The predicted tone map's search: alpha from PREDICTED_ALPHA_MAX down to PREDICTED_ALPHA_MIN
#: on a 0.1 grid, beta on PREDICTED_BETAS times the image's mean white-screen level, then
#: alpha +-0.06 in 0.01 steps and beta +-0.03 in 0.005 steps around the best; a video frame
#: starts from the previous frame's choice (a local search). Alpha above 1 (brighter than the
#: white screen would show) can be the best a dim or coloured screen can do.
PREDICTED_ALPHA_MIN = 0.2
PREDICTED_ALPHA_MAX = 1.5
PREDICTED_BETAS = np.linspace(-0.3, 0.6, 31)
#: Pixels of the thumbnail the predicted tone map looks at, at most (every k-th row and column).
PREDICTED_PIXELS = 1024


#: Linear sRGB (D65) -> CIE XYZ, rows X, Y, Z, each divided by the white point's component.
_RGB_TO_XYZN = np.array(
    [[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722], [0.0193, 0.1192, 0.9505]]
) / np.array([[0.95047], [1.0], [1.08883]])


def linear_lab(rgb: np.ndarray) -> np.ndarray:
    """CIELAB (..., 3) of linear RGB taken as linear sRGB (D65), 1 = white: the colour
    space the evaluation's CIEDE2000 measures in."""
    t = np.maximum(rgb, 0.0) @ _RGB_TO_XYZN.T
    f = np.where(t > 0.008856, np.cbrt(t), 7.787 * t + 16.0 / 116.0)
    return np.stack(
        [
            116.0 * f[..., 1] - 16.0,
            500.0 * (f[..., 0] - f[..., 1]),
            200.0 * (f[..., 1] - f[..., 2]),
        ],
        axis=-1,
    )


def delta_e94(lab: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """CIE94 colour difference (graphic arts) of ``lab`` from ``ref``, per pixel: chroma and
    hue weighted down for saturated references, as CIEDE2000 does, at a fraction of its cost."""
    c_ref = np.hypot(ref[..., 1], ref[..., 2])
    c = np.hypot(lab[..., 1], lab[..., 2])
    dl = lab[..., 0] - ref[..., 0]
    dc = c - c_ref
    dh2 = np.maximum(np.sum((lab[..., 1:] - ref[..., 1:]) ** 2, axis=-1) - dc * dc, 0.0)
    return np.sqrt(dl * dl + (dc / (1.0 + 0.045 * c_ref)) ** 2 + dh2 / (1.0 + 0.015 * c_ref) ** 2)


def choose_predicted_tone_map(
    u: np.ndarray,
    v: np.ndarray,
    c: np.ndarray,
    m: np.ndarray,
    white: np.ndarray,
    lo: np.ndarray | float = 0.0,
    hi: np.ndarray | float = 1.0,
    start: ToneMap | None = None,
    viewers: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
) -> ToneMap:
    """(alpha, beta) minimising the *predicted* perceptual error of the compensated image.

    The light asked for is y = alpha u + beta v + c per pixel-channel (u = M^-1 C_w, v =
    M^-1 1, c = -M^-1 A: :func:`~viewcomp.calib.model.reference.tone_terms`); the projector
    gives clip(y, lo, hi), so the screen shows alpha C_w + beta + M (clip(y) - y). The error
    is the mean CIE94 colour difference between what it shows and C_w, what the white screen
    would show (both in CIELAB, the camera's linear RGB taken as linear sRGB): what a viewer
    sees, where the paper's Eq. 22 counts clipped pixel-channels however far off they are,
    and prefers a dark image on a coloured screen that cannot reach the white's levels in
    some channel. The error is not convex in (alpha, beta) there (hue trades against
    lightness), so the search is a grid, then a finer grid around the best.

    Args:
        u, v, c: (..., 3) from tone_terms, linear projector light.
        m: (..., 3, 3) the screen's mixing at the eye (what tone_terms inverted).
        white: (..., 3) C_w, linear camera units.
        lo, hi: the projector light's bounds (0 and 1 for the per-pixel method).
        start: a previous choice (the last video frame's): a local search around it instead
            of the whole grid.
        viewers: an audience (docs/MODEL.md section 6): (M_k (K, ..., 3, 3), A_k (K, ..., 3),
            w_k (K,)), the screen at each viewer's eye and the viewers' weights; y then comes
            from the audience's least squares (u, v, c of its solve), viewer k sees
            M_k clip(y) + A_k, and the error is the weighted mean over the viewers. ``m`` is
            unused then.

    Returns:
        The ToneMap (``clipped``: the fraction of pixel-channels clipped; ``cost``: the
        error).
    """
    shape = np.shape(u)
    n = int(np.prod(shape[:-1]))
    if n == 0:
        return ToneMap(1.0, 0.0, 0.0, 0.0)
    err = _PredictedError(u, v, c, m, white, lo, hi, viewers)
    search = _GridSearch(err, max(float(err.w.mean()), 1e-4))
    if start is None:
        alphas = np.arange(PREDICTED_ALPHA_MAX, PREDICTED_ALPHA_MIN - 1e-9, -0.1)
        best = search.visit(np.round(alphas, 2), PREDICTED_BETAS)
        search.visit(
            np.round(np.arange(best.alpha + 0.06, best.alpha - 0.0601, -0.01), 2),
            search.best_k + np.linspace(-0.03, 0.03, 13),
        )
    else:
        # A local search: a 5 x 5 grid around the centre, moved to the best until it stays.
        a0, k0 = float(start.alpha), round(float(start.beta) / search.scale, 6)
        for _ in range(4):
            best = search.visit(
                np.round(a0 + np.array([0.0, 0.01, -0.01, 0.02, -0.02]), 2),
                k0 + np.array([0.0, 0.004, -0.004, 0.008, -0.008]),
            )
            if (best.alpha, search.best_k) == (a0, k0):
                break
            a0, k0 = best.alpha, search.best_k
    assert search.best is not None
    return search.best


class _PredictedError:
    """:func:`choose_predicted_tone_map`'s error of each (alpha, beta): its inputs flattened
    to pixels and subsampled to at most about PREDICTED_PIXELS of them."""

    def __init__(
        self,
        u: np.ndarray,
        v: np.ndarray,
        c: np.ndarray,
        m: np.ndarray,
        white: np.ndarray,
        lo: np.ndarray | float,
        hi: np.ndarray | float,
        viewers: tuple[np.ndarray, np.ndarray, np.ndarray] | None,
    ) -> None:
        shape = np.shape(u)
        n = int(np.prod(shape[:-1]))
        k = max(1, int(np.ceil(n / PREDICTED_PIXELS)))

        def flat(x: np.ndarray) -> np.ndarray:
            return np.broadcast_to(np.asarray(x, np.float64), shape).reshape(-1, 3)[::k]

        self.u, self.v, self.c, self.w = flat(u), flat(v), flat(c), flat(white)
        self.lo = np.broadcast_to(np.asarray(lo, np.float64), (3,))
        self.hi = np.broadcast_to(np.asarray(hi, np.float64), (3,))
        self.goal = linear_lab(self.w)
        self.viewers = viewers
        if viewers is None:
            self.m = np.broadcast_to(np.asarray(m, np.float64), (*shape, 3)).reshape(-1, 3, 3)[::k]
        else:
            mk, ak, wk = (np.asarray(x, np.float64) for x in viewers)
            nk = len(wk)
            self.mk = np.broadcast_to(mk, (nk, *shape, 3)).reshape(nk, -1, 3, 3)[:, ::k]
            self.ak = np.broadcast_to(ak, (nk, *shape)).reshape(nk, -1, 3)[:, ::k]
            self.wk = wk / wk.sum()

    def __call__(self, alpha: float, betas: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(mean CIE94 error, fraction clipped) for ``alpha`` and each of ``betas``."""
        y = alpha * self.u + betas[:, None, None] * self.v + self.c
        short = np.clip(y, self.lo, self.hi) - y
        if self.viewers is None:  # M y + A = T exactly: what shows is T + M (clip(y) - y)
            shown = alpha * self.w + betas[:, None, None] + np.einsum("nij,knj->kni", self.m, short)
            err = np.mean(delta_e94(linear_lab(shown), self.goal), axis=1)
        else:
            err = np.zeros(len(betas))
            for j in range(len(self.wk)):
                seen = np.einsum("nij,knj->kni", self.mk[j], y + short) + self.ak[j]
                err += self.wk[j] * np.mean(delta_e94(linear_lab(seen), self.goal), axis=1)
        return err, np.mean(short != 0.0, axis=(1, 2))


class _GridSearch:
    """The best (alpha, beta) over the grids visited so far; beta = k * scale, k on the grids'
    rounded steps (0 stays exactly 0)."""

    def __init__(self, error: _PredictedError, scale: float) -> None:
        self.error = error
        self.scale = scale
        self.best: ToneMap | None = None
        self.best_k = 0.0

    def visit(self, alphas: np.ndarray, ks: np.ndarray) -> ToneMap:
        """Try every alpha (within the limits) with every k; returns the best so far."""
        ks = np.round(ks, 6)
        for alpha in alphas:
            if not PREDICTED_ALPHA_MIN - 1e-9 <= alpha <= PREDICTED_ALPHA_MAX + 1e-9:
                continue
            err, clipped = self.error(float(alpha), ks * self.scale)
            i = int(np.argmin(err))
            if self.best is None or err[i] < self.best.cost - 1e-15:
                self.best_k = float(ks[i])
                self.best = ToneMap(
                    float(alpha), self.best_k * self.scale, float(clipped[i]), float(err[i])
                )
        assert self.best is not None
        return self.best


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
