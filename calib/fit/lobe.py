"""The per-pixel method's specular lobe: a tabulated lobe per channel, fitted to what the
calibration camera saw (docs/MODEL.md section 4).

The specular ratio of the real to the white screen (ambient removed), per pixel x and channel,

    s(x) = b + lobe(t(x)),     t = sqrt(1 - cos angle)  (viewcomp.calib.model.lobe)

is a diffuse baseline b plus a lobe that depends on the angle between the normal and the half
vector (``half``, the microfacet parametrisation) or between the mirror direction and the
view (``mirror``, Phong's). Measured glossy lobes are a ~1-degree spike on a broad haze, often
coloured; no single power law fits them. So the lobe is a table: the median of s over the
pixels the camera saw in each bin of the table's coordinate, lightly smoothed, minus the
baseline (below), never negative. Both parametrisations are fitted and the one with the
smaller residual is kept.

The baseline is the higher of two levels: the floor of a fit of b + c exp(-k t^2) to the
outer part of the curve (a Phong lobe's shape, and a smooth tail for any lobe), and the level
at the farthest angles seen (so no decrease the camera never saw is extrapolated). A camera
coarser than the projector sees the frame's outer lines mixed with the unlit surround, and
those lines (the edge zone, :mod:`viewcomp.calib.geo.edgezone`) hold copies of inner values:
they are left out of the samples, and over their angles - the frame's farthest, which a finer
camera measures - the curve continues its straight-line trend (never rising) before the
baseline is read, so that a coarse camera's baseline is not the level of nearer angles. Outside
the angles the camera saw: nearer the peak than any pixel seen (the peak clipped or outside
the image), the nearest value is held; beyond the farthest, the lobe is 0 (the diffuse level),
reached smoothly (the tail's decay exp(-k t^2) from its last value, k >= 5). It is never negative
and never larger than what was measured.

For comparison the fit also reports the residual of the previous model, b + kappa
(R.V)^gamma by non-linear least squares, and of the paper's power law on the same samples.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import pairwise

import numpy as np

from viewcomp.calib.errors import FitError
from viewcomp.calib.model.lobe import LOBE_N, LOBE_PARAMS, lobe_lookup, lobe_position
from viewcomp.calib.world.geometry import ScreenGeometry

#: Samples in each bin of the table's coordinate whose median is the lobe there.
MIN_BIN_SAMPLES = 24

#: Smallest decay rate k of the tail exp(-k t^2): at 90 degrees (t = 1) it is below 1 %.
TAIL_MIN_RATE = 5.0

#: Share of the seen coordinate range, at its far end, whose median level is the baseline.
FAR_SHARE = 0.03

#: Share of the seen coordinate range, at its far end, whose straight-line trend is continued
#: over the angles of the frame's edge zone (pixels whose values are copies, not measurements).
TREND_SHARE = 0.1


@dataclass(frozen=True)
class LobeFit:
    """The fitted lobe and how well it fits.

    Attributes:
        param: ``"half"`` or ``"mirror"`` (see the module docstring).
        table: (LOBE_N, 3) lobe values (units of s) at t = k / (LOBE_N - 1), >= 0.
        baseline: (3,) b, the diffuse ratio (units of s).
        t_seen: (lo, hi) the coordinates the camera saw with data.
        rms: (3,) RMS residual of s - (b + lobe(t)) (units of s), on the pixels with R.V > 0
            (at most ~20000 of them), as the three below.
        rms_other: (3,) the same for the other parametrisation's table.
        rms_phong: (3,) the previous model's, b + kappa (R.V)^gamma, least squares.
        rms_power_law: (3,) the paper's log s = a + gamma log(R.V), in units of s.
        peak: (3,) the table's largest value (units of s).
        samples: pixels used; ``masked``: pixels left out as clipped or not finite.
        message: a line for the user.
    """

    param: str
    table: np.ndarray
    baseline: np.ndarray
    t_seen: tuple[float, float]
    rms: np.ndarray
    rms_other: np.ndarray
    rms_phong: np.ndarray
    rms_power_law: np.ndarray
    peak: np.ndarray
    samples: int
    masked: int
    message: str

    @property
    def half(self) -> bool:
        """True for the half-vector parametrisation."""
        return self.param == "half"

    def value(self, t: np.ndarray) -> np.ndarray:
        """The lobe at coordinates t (...): (..., 3) float64."""
        return lobe_lookup(self.table, t)

    def at(self, geometry: ScreenGeometry, eye: np.ndarray) -> np.ndarray:
        """The lobe on the grid seen from ``eye``: (H, W, 3) float64 (looked up a block of
        rows at a time: the lookup's temporaries are several times the result)."""
        t = lobe_position(geometry.refl, geometry.pos, eye, self.half, np.float64)
        out = np.empty((*t.shape, 3))
        for rows in np.array_split(np.arange(t.shape[0]), max(1, t.size >> 18)):
            out[rows[0] : rows[-1] + 1] = self.value(t[rows[0] : rows[-1] + 1])
        return out


def _continue_trend(curve: np.ndarray, cells: int) -> np.ndarray:
    """(cells, 3): ``curve`` (m, 3) continued ``cells`` cells past its end along the straight
    line fitted to its last :data:`TREND_SHARE` (at least 5 cells), never above its last value
    (no rise the camera did not see) nor below 0."""
    k = min(curve.shape[0], max(5, round(TREND_SHARE * curve.shape[0])))
    x = np.arange(k, dtype=np.float64)
    icept, slope = np.polynomial.polynomial.polyfit(x, curve[-k:], 1)  # (3,) each
    ahead = np.arange(k, k + cells, dtype=np.float64)[:, None]
    return np.clip(slope * ahead + icept, 0.0, curve[-1])


def _table(
    t: np.ndarray, s: np.ndarray, t_end: float | None = None
) -> tuple[np.ndarray, np.ndarray, tuple[float, float]]:
    """(table (LOBE_N, 3), baseline (3,), (t_lo, t_hi)) from samples t (n,) and s (n, 3).

    ``t_end``: the farthest coordinate on the frame, edge zone included; where it lies past
    the farthest sample, the curve is continued there (:func:`_continue_trend`) before the
    baseline is read, so that the baseline is the level at the frame's farthest angles as a
    camera that measured them would read it, not the level of nearer ones."""
    from scipy.ndimage import gaussian_filter1d  # scipy is imported by fits only: loading is faster

    n = LOBE_N
    cell = np.clip(np.rint(t * (n - 1)).astype(np.int64), 0, n - 1)
    order = np.argsort(cell, kind="stable")
    cs, ss = cell[order], s[order]
    starts = np.flatnonzero(np.r_[True, cs[1:] != cs[:-1]])
    # Consecutive cells merge into bins of at least MIN_BIN_SAMPLES samples (one cell where
    # the camera saw many pixels, e.g. near the peak; wider where it saw few), each bin's
    # value the median of its samples at the mean cell of its samples.
    bin_starts = [0]
    count = 0
    for k in range(starts.size):
        end = starts[k + 1] if k + 1 < starts.size else cs.size
        count += end - starts[k]
        if count >= MIN_BIN_SAMPLES and k + 1 < starts.size:
            bin_starts.append(int(starts[k + 1]))
            count = 0
    edges = np.r_[bin_starts, cs.size]
    if edges.size - 1 < 4:
        raise FitError(
            "screen/gray",
            "the camera saw too few distinct angles of the specular lobe to tabulate it "
            "(the projected image is too small or the geometry degenerate): check rig.toml",
        )
    bins = list(pairwise(edges.tolist()))
    cells = np.array([cs[a:b].mean() for a, b in bins])
    med = np.stack([np.median(ss[a:b], axis=0) for a, b in bins])
    # Fill the cells between seen ones, then smooth lightly (noise of the medians); a one-cell
    # sigma keeps a one-degree spike (about 13 cells wide in t).
    lo, hi = int(np.ceil(cells[0])), int(np.floor(cells[-1]))
    grid = np.arange(lo, hi + 1)
    curve = np.stack([np.interp(grid, cells, med[:, c]) for c in range(3)], axis=1)
    curve = gaussian_filter1d(curve, 1.0, axis=0, mode="nearest")
    seen = (lo / (n - 1), hi / (n - 1))
    end = hi if t_end is None else min(n - 1, max(hi, int(np.floor(t_end * (n - 1)))))
    if end > hi:
        curve = np.concatenate([curve, _continue_trend(curve, end - hi)])
        hi = end
        grid = np.arange(lo, hi + 1)
    t_grid = grid / (n - 1)
    fits = np.array([_tail(t_grid, curve[:, c]) for c in range(3)])
    rate = fits[:, 1]
    # The baseline is the higher of the tail fit's floor and the level at the farthest angles
    # seen. Below the latter it would extrapolate a decrease the camera never saw (a broad
    # sheen that does not flatten within its view), which can make compensation for a far
    # eye worse than none; above it, the curve sinking past the lobe is the diffuse part
    # falling off with angle, which no eye position changes much. The lobe is what stands
    # above both, and ends at 0 at the farthest angles seen.
    far = max(3, round(FAR_SHARE * curve.shape[0]))
    base = np.maximum(fits[:, 0], np.median(curve[-far:], axis=0))
    lobe = np.maximum(curve - base, 0.0)
    table = np.empty((n, 3))
    table[:lo] = lobe[0]
    table[lo : hi + 1] = lobe
    # Beyond the farthest angle seen: the tail's own decay, exp(-k t^2), from the last value.
    t_far = np.arange(hi + 1, n) / (n - 1)
    t_hi = hi / (n - 1)
    table[hi + 1 :] = lobe[-1] * np.exp(-rate[None, :] * (t_far[:, None] ** 2 - t_hi**2))
    return table, base, seen


def _tail(t: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """(b, k) of y ~ b + c exp(-k t^2) fitted to the outer part of a lobe curve (the
    samples past the middle of the seen range, or below a third of its peak over b).

    exp(-k t^2) is a Phong lobe's shape ((R.V)^k = (1 - t^2)^k ~ exp(-k t^2)) and a smooth
    tail for any lobe; k >= TAIL_MIN_RATE makes it reach the diffuse level b by 90 degrees.
    """
    from scipy.optimize import least_squares

    lo_level = float(np.min(y))
    outer = (t >= t[0] + 0.5 * (t[-1] - t[0])) | (y - lo_level <= (np.max(y) - lo_level) / 3)
    to, yo = t[outer], y[outer]
    if to.size < 5 or np.ptp(to) <= 0:
        return float(np.median(y[-max(1, round(FAR_SHARE * y.size)) :])), TAIL_MIN_RATE

    def resid(p: np.ndarray) -> np.ndarray:
        return p[0] + p[1] * np.exp(-p[2] * to * to) - yo

    b0 = max(float(yo.min()), 0.0)
    c0 = max(float(yo.max() - b0), 1e-6) * float(np.exp(min(to.min() ** 2 * 30.0, 50.0)))
    fit = least_squares(
        resid,
        [b0, c0, 30.0],
        bounds=([0.0, 0.0, TAIL_MIN_RATE], [np.inf, np.inf, 1e5]),
        x_scale="jac",
    )
    return float(fit.x[0]), float(fit.x[2])


def _phong_rms(rv: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """RMS residuals (3,) of b + kappa (R.V)^gamma (least squares) and of the paper's power
    law log s = a + gamma log(R.V), both on samples rv (n,) > 0 and s (n, 3)."""
    from scipy.optimize import least_squares

    lx = np.log(np.maximum(rv, 1e-9))

    def model(p: np.ndarray) -> np.ndarray:
        return p[0:3] + p[3:6] * np.exp(p[6] * lx)[:, None]

    def resid(p: np.ndarray) -> np.ndarray:
        return (model(p) - y).ravel()

    b0 = np.maximum(np.percentile(y, 5, axis=0), 0.0)
    k0 = np.maximum(np.percentile(y, 99.5, axis=0) - b0, 1e-3)
    best = None
    for g0 in (5.0, 20.0, 80.0):
        r = least_squares(
            resid,
            np.concatenate([b0, k0, [g0]]),
            bounds=([0] * 6 + [0.5], [np.inf] * 6 + [5000.0]),
            x_scale="jac",
        )
        if best is None or r.cost < best.cost:
            best = r
    assert best is not None  # the loop above runs at least once
    rms = np.sqrt(np.mean((model(best.x) - y) ** 2, axis=0))
    design = np.stack([np.ones_like(lx), lx], axis=1)
    pl = np.empty(3)
    for ch in range(3):
        coef, *_ = np.linalg.lstsq(design, np.log(np.maximum(y[:, ch], 1e-9)), rcond=None)
        pl[ch] = np.sqrt(np.mean((np.exp(design @ coef) - y[:, ch]) ** 2))
    return rms, pl


def _fit_param(
    geometry: ScreenGeometry,
    name: str,
    step: int,
    ok: np.ndarray,
    y: np.ndarray,
    sub: np.ndarray,
    filled: np.ndarray | None,
) -> tuple[np.ndarray, np.ndarray, tuple[float, float], np.ndarray]:
    """The lobe tabulated over one parametrisation (``name``: "half" or "mirror") of the
    camera's view: (table, baseline, angles seen, rms (3,) on the samples ``sub``); the
    curve continued over the angles of the ``filled`` pixels (subsampled like ``ok``)."""
    t = lobe_position(geometry.refl, geometry.pos, geometry.camera, name == "half", np.float64)
    t = t[::step, ::step]
    t_end = None
    if filled is not None and np.any(filled):
        t_end = float(np.max(t[filled | ok]))
    t = t[ok]
    table, base, seen = _table(t, y, t_end)
    pred = base + lobe_lookup(table, t[sub])
    rms = np.sqrt(np.mean((pred - y[sub]) ** 2, axis=0))
    return table, base, seen, rms


def _samples(
    s: np.ndarray, valid: np.ndarray | None, filled: np.ndarray | None, step: int
) -> tuple[np.ndarray, np.ndarray | None, int]:
    """(ok, filled, masked) on the grid subsampled by ``step``: ``ok`` the pixels to sample
    (finite, ``valid``, not ``filled``), ``filled`` subsampled, ``masked`` the count left out
    as clipped or not finite."""
    ok = np.all(np.isfinite(s), axis=-1)
    if valid is not None:
        ok &= valid
    ok = ok[::step, ::step]
    masked = int(ok.size - np.count_nonzero(ok))
    if filled is not None:
        filled = filled[::step, ::step]
        ok = ok & ~filled
    return ok, filled, masked


def fit_lobe(
    s: np.ndarray,
    geometry: ScreenGeometry,
    valid: np.ndarray | None = None,
    param: str | None = None,
    step: int = 1,
    filled: np.ndarray | None = None,
) -> LobeFit:
    """Tabulate the lobe from the specular ratio the calibration camera saw.

    Args:
        s: (H, W, 3) specular ratio of the real to the white screen, ambient removed
            (dimensionless; ~albedo ratio off the highlight, tens to hundreds on a glossy peak).
        geometry: the rig's per-pixel geometry on the same grid (its camera is the view).
        valid: (H, W) bool, pixels to use (False: clipped or masked), default all.
        param: ``"half"`` or ``"mirror"`` to force a parametrisation; None: the one with the
            smaller residual.
        step: subsampling of the pixels (1: all).
        filled: (H, W) bool, pixels whose values are not measurements but copies (the
            frame's edge zone, :mod:`viewcomp.calib.geo.edgezone`), default none: left out
            of the samples, and the curve continued over their angles (the module docstring).

    Returns:
        the :class:`LobeFit`; a lobe below the noise is set to zero ("matte").

    Raises:
        FitError: too few usable pixels or angles, naming the capture.
    """
    if s.shape != (*geometry.pos.shape[:2], 3):
        raise ValueError(f"s must be {(*geometry.pos.shape[:2], 3)}, got {s.shape}")
    if param is not None and param not in LOBE_PARAMS:
        raise ValueError(f"param must be one of {LOBE_PARAMS}, got {param!r}")
    ok, filled, masked = _samples(s, valid, filled, step)
    # float32 samples (what the captures hold); the table's medians pick among them and the
    # comparison fits below run in float64.
    y = s[::step, ::step][ok].astype(np.float32)
    if y.shape[0] < 50:
        raise FitError(
            "screen/gray",
            f"only {y.shape[0]} usable pixels to fit the specular lobe ({masked} clipped or "
            "not finite): capture with a lower exposure or with --hdr",
        )
    # Every residual is measured on the same samples: the pixels with R.V > 0 (where the
    # power law is defined), at most about 20000 of them.
    rv = geometry.rv(geometry.camera)[::step, ::step][ok]
    pos = np.flatnonzero(rv > 0)
    sub = pos[:: max(1, pos.size // 20000)] if pos.size >= 20 else np.arange(y.shape[0])
    fits = {name: _fit_param(geometry, name, step, ok, y, sub, filled) for name in LOBE_PARAMS}
    chosen = param or min(LOBE_PARAMS, key=lambda k: float(np.mean(fits[k][3])))
    other = next(k for k in LOBE_PARAMS if k != chosen)
    table, base, seen, rms = fits[chosen]
    nan = np.full(3, np.nan)
    rms_phong, rms_pl = (
        _phong_rms(rv[sub], y[sub].astype(np.float64)) if pos.size >= 20 else (nan, nan)
    )
    peak = table.max(axis=0)
    # Matte: no cell of the lobe stands out of the samples' scatter about the fit.
    message = f"tabulated lobe ({chosen} angle), peak {np.array2string(peak, precision=3)}"
    if np.all(peak < 3.0 * rms + 1e-3):
        table = np.zeros_like(table)
        peak = np.zeros(3)
        message = "no specular lobe above the noise: treated as matte"
    if masked:
        message += f"; {masked} pixels left out (clipped or not finite)"
    if filled is not None and np.any(filled):
        message += f"; continued over the edge zone's angles ({np.count_nonzero(filled)} pixels)"
    return LobeFit(
        param=chosen,
        table=table,
        baseline=base,
        t_seen=seen,
        rms=rms,
        rms_other=fits[other][3],
        rms_phong=rms_phong,
        rms_power_law=rms_pl,
        peak=peak,
        samples=int(y.shape[0]),
        masked=masked,
        message=message,
    )


def black_lobe_share(
    black_ratio: np.ndarray, lobe_cam: np.ndarray, baseline: np.ndarray, valid: np.ndarray
) -> np.ndarray:
    """eta (3,) in [0, 1]: the share of the white screen's black level that is projector
    light, which the lobe reflects (the projector's black leak), the rest being room light.

    On the black capture the real screen shows A_c = (b + lobe_cam eta) A_w per pixel: the
    leak's highlight sits where the gray pattern's does, scaled by eta. So eta is the
    least-squares slope of (A_c / A_w - b) on lobe_cam over the pixels where the lobe seen by
    the camera is above a tenth of its peak.

    Args:
        black_ratio: (H, W, 3) A_c / A_w, the black captures' ratio.
        lobe_cam: (H, W, 3) the fitted lobe seen from the calibration camera.
        baseline: (3,) b of the lobe fit.
        valid: (H, W) pixels to use.

    Returns:
        (3,) eta; 0 where the lobe is zero or too few pixels show it.
    """
    out = np.zeros(3)
    for c in range(3):
        lobe = lobe_cam[..., c]
        peak = float(lobe.max(initial=0.0))
        use = valid & (lobe > 0.1 * peak) & np.isfinite(black_ratio[..., c]) if peak > 0 else None
        if use is None or np.count_nonzero(use) < 20:
            continue
        x, y = lobe[use], black_ratio[..., c][use] - baseline[c]
        out[c] = float(np.clip(np.dot(x, y) / max(float(np.dot(x, x)), 1e-12), 0.0, 1.0))
    return out
