"""The paper's method (docs/MODEL.md section 2, steps 1-7), with the errata of section 3 applied.

All images here are linearised captures on the projector grid: float (H, W, 3), linear
camera units 0..1. Pattern names follow Table 1: ``red green blue gray ramp``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from viewcomp.calib.errors import FitError
from viewcomp.calib.io.patterns import ramp_levels
from viewcomp.calib.model.runtime import RuntimeModel
from viewcomp.calib.world.geometry import ScreenGeometry

CHANNEL_PATTERNS = ("red", "green", "blue")
INV_LUT_SIZE = 1024


# -- step 1: vignetting and specular map (Eqs. 2-4) -----------------------------------------


def specular_map(gray_screen: np.ndarray, gray_white: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """S_90 = (L_U,90 / n) / (Q / max Q), per colour channel (Eqs. 2-4).

    Args:
        gray_screen: L_U,90, the gray pattern on the real screen, (H, W, 3) linear.
        gray_white: Q, the gray pattern on the white screen, (H, W, 3) linear.

    Returns:
        S_90 (H, W, 3) (max about 1) and n (3,), the normalising constant of Eq. 3.
    """
    n = gray_screen.reshape(-1, 3).max(axis=0)
    qmax = gray_white.reshape(-1, 3).max(axis=0)
    if np.any(n <= 0) or np.any(qmax <= 0):
        raise FitError("gray", "the gray capture is black in some channel: is the projector on?")
    q_hat = np.maximum(gray_white / qmax, 1e-6)
    return (gray_screen / n) / q_hat, n


# -- step 2: the Phong fit (Eqs. 5, 7, 8) ---------------------------------------------------


@dataclass(frozen=True)
class PhongFit:
    """log s = log(k_s i_s) + gamma log(R.V), per channel, and how well it fits.

    ``rms`` is the residual in log units, ``r2`` the coefficient of determination, ``samples``
    the number of pixels used, ``mode`` "all" (Eq. 8) or "row" (Eq. 7).
    """

    ksis: np.ndarray  # (3,)
    gamma: np.ndarray  # (3,)
    rms: np.ndarray  # (3,)
    r2: np.ndarray  # (3,)
    samples: int
    mode: str

    def predict(self, rv: np.ndarray) -> np.ndarray:
        """k_s i_s (R.V)^gamma where R.V > 0, else 0: (H, W) -> (H, W, 3)."""
        c = rv[..., None]
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            v = self.ksis * np.where(c > 0, c, 1.0) ** self.gamma
        return np.where(c > 0, v, 0.0)


def camera_row(geometry: ScreenGeometry) -> int:
    """The projector row whose screen points lie closest to the camera's height (Eq. 7)."""
    y = geometry.pos[:, geometry.pos.shape[1] // 2, 1]
    return int(np.argmin(np.abs(y - geometry.camera[1])))


def fit_phong(s90: np.ndarray, rv90: np.ndarray, mode: str = "all", row: int = 0) -> PhongFit:
    """Linear regression of log S_90 on log(R.V) over pixels with R.V > 0 (Eq. 7 or 8).

    Args:
        s90: (H, W, 3) the specular map of ``specular_map``.
        rv90: (H, W) R.V toward the calibration camera.
        mode: "all" (Eq. 8, every pixel) or "row" (Eq. 7, the row at the camera's height).
        row: the row for mode "row".

    Raises:
        FitError: too few usable pixels, or no spread of R.V to regress on.
    """
    if mode == "row":
        s, rv = s90[row : row + 1], rv90[row : row + 1]
    elif mode == "all":
        s, rv = s90, rv90
    else:
        raise ValueError(f"mode must be 'all' or 'row', got {mode!r}")
    ok = (rv > 0) & np.all(s > 0, axis=-1)
    x = np.log(rv[ok])
    if x.size < 10 or np.ptp(x) < 1e-4:
        raise FitError(
            "gray",
            "too few pixels with R.V > 0 (or no spread of R.V) to fit the Phong model: check "
            "the rig geometry in rig.toml",
        )
    design = np.stack([np.ones_like(x), x], axis=1)
    ksis, gamma, rms, r2 = (np.zeros(3) for _ in range(4))
    for ch in range(3):
        y = np.log(s[..., ch][ok])
        coef, *_ = np.linalg.lstsq(design, y, rcond=None)
        res = y - design @ coef
        ksis[ch], gamma[ch] = np.exp(coef[0]), coef[1]
        rms[ch] = np.sqrt(np.mean(res**2))
        var = np.var(y)
        r2[ch] = 1.0 - np.mean(res**2) / var if var > 0 else 0.0
    return PhongFit(ksis, gamma, rms, r2, int(x.size), mode)


# -- step 4: Grossberg's model (Eqs. 11-20, Eq. 16 with the errata) -------------------------


def mixing_from_means(means: dict[str, np.ndarray], check_order: bool = True) -> np.ndarray:
    """W~[i][j] = {dL_j}_i / {dL_j}_j with dL_j = mean(L_j) - mean(L_U) (Eq. 16, corrected).

    Args:
        means: "red", "green", "blue", "gray" -> (3,) mean linear capture.

        check_order: refuse captures whose colour patterns look swapped (for captured means;
            predicted means at another eye are not captures).

    Returns:
        (3, 3) W~ with ones on the diagonal; column j is normalised by its own diagonal entry.
    """
    w = np.empty((3, 3))
    gray = np.asarray(means["gray"], np.float64)
    for j, name in enumerate(CHANNEL_PATTERNS):
        d = np.asarray(means[name], np.float64) - gray
        # Relative to gray, a pattern raises its own channel most, whatever the screen's
        # colour (the albedo cancels in d / gray): otherwise the captures are mixed up.
        if check_order and d[j] > 1e-6 and int(np.argmax(d / np.maximum(gray, 1e-9))) != j:
            raise FitError(
                name,
                f"raises channel {'RGB'[int(np.argmax(d / np.maximum(gray, 1e-9)))]} more "
                f"than {'RGB'[j]}: the captures look swapped - check that {name}.png was "
                f"captured while the {name} pattern was projected",
            )
        if d[j] <= 1e-6:
            raise FitError(
                name,
                f"the {name} pattern is not brighter than gray in its own channel "
                f"(difference {d[j]:.2g}): patterns in the wrong order, or the camera's "
                "white balance is not locked",
            )
        w[:, j] = d / d[j]
    return w


def level_means(column_values: np.ndarray) -> np.ndarray:
    """Mean of a ramp's per-column values for every level 0..255: (W, 3) -> (256, 3).

    Levels that no column shows (ramps narrower than 256) are interpolated.
    """
    width = column_values.shape[0]
    lv = ramp_levels(width).astype(np.int64)
    counts = np.bincount(lv, minlength=256).astype(np.float64)
    out = np.empty((256, 3))
    have = counts > 0
    for ch in range(3):
        sums = np.bincount(lv, weights=column_values[:, ch], minlength=256)
        m = sums[have] / counts[have]
        out[:, ch] = np.interp(np.arange(256), np.flatnonzero(have), m)
    return out


def monotone_lut(samples: np.ndarray, name: str = "ramp") -> np.ndarray:
    """A strictly increasing (256, 3) curve regressed from per-level samples (isotonic).

    Raises:
        FitError: the samples are flat or far from monotone (a reversed or wrong ramp).
    """
    from scipy.optimize import isotonic_regression  # imported when fitting: loading is faster

    out = np.empty_like(samples, dtype=np.float64)
    for ch in range(3):
        y = samples[:, ch]
        fit = isotonic_regression(y).x
        span = fit[-1] - fit[0]
        if span <= 1e-4:
            raise FitError(
                name,
                f"the ramp is flat in channel {'RGB'[ch]}: project ramp.png (dark on the left, "
                "bright on the right) and capture it again",
            )
        misfit = np.sqrt(np.mean((y - fit) ** 2))
        if misfit > 0.2 * span:
            raise FitError(
                name,
                f"the ramp is not monotone in channel {'RGB'[ch]} (misfit {misfit / span:.0%} "
                "of its range): was it projected mirrored, or another pattern captured?",
            )
        out[:, ch] = fit + np.linspace(0.0, 1e-6 * span, 256)
    return out


def inverse_lut(lut: np.ndarray, size: int = INV_LUT_SIZE) -> tuple[np.ndarray, ...]:
    """Invert a strictly increasing (256, 3) curve: (size, 3) level/255 on [lo, hi] per channel.

    Sample k sits at y = lo + (hi - lo) (k / (size - 1))^2 (see ``reference.lut_inverse``).
    """
    lo, hi = lut[0].copy(), lut[-1].copy()
    inv = np.empty((size, 3))
    levels = np.arange(256, dtype=np.float64)
    warp = np.linspace(0.0, 1.0, size) ** 2  # uniform in sqrt((y - lo) / (hi - lo))
    for ch in range(3):
        ys = lo[ch] + (hi[ch] - lo[ch]) * warp
        inv[:, ch] = np.interp(ys, lut[:, ch], levels) / 255.0
    return inv, lo, hi


def regress_rho(samples: np.ndarray, name: str = "ramp", strict: bool = True) -> np.ndarray:
    """rho(I) = a + b (I/255)^g per channel, least squares on per-level samples (Eq. 20).

    A parametric regression, as the paper's "regression of L~_S": the projector's response
    has this shape, and a few parameters average over the spatial effects that the ramp
    confounds with the level (each level sits at its own column, with its own vignetting,
    fall-off and highlight), where a free-form curve would copy them.

    Args:
        samples: (256, 3) mean decoupled value per level.
        name: the capture, for error messages.
        strict: refuse a flat, decreasing or badly fitting ramp (captures); predicted ramps
            (Eq. 10 at another eye) are regressed whatever they look like.

    Returns:
        (256, 3) strictly increasing curve.

    Raises:
        FitError: (strict) a ramp that is flat or decreasing, or that no such curve fits.
    """
    x = np.arange(256) / 255.0
    out = np.empty((256, 3))
    for ch in range(3):
        y = samples[:, ch]
        span = float(y[-16:].mean() - y[:16].mean())
        if strict and span <= 1e-4:
            raise FitError(
                name,
                f"the ramp is flat or decreasing in channel {'RGB'[ch]}: project ramp.png "
                "(dark on the left, bright on the right) and capture it again",
            )
        a, b, g = _fit_power_curve(x, y)
        fit = a + b * x**g
        misfit = float(np.sqrt(np.mean((y - fit) ** 2)))
        if strict and misfit > 0.25 * span:
            raise FitError(
                name,
                f"the ramp is not monotone in channel {'RGB'[ch]} (misfit {misfit / span:.0%} "
                "of its range): was it projected mirrored, or another pattern captured?",
            )
        out[:, ch] = fit
    return out


def _fit_power_curve(x: np.ndarray, y: np.ndarray) -> tuple[float, float, float]:
    """Least squares a + b x^g with b > 0, g in [0.2, 8]: linear in (a, b) for each g, so g is
    searched on a geometric grid, refined three times around the best (to ~1e-6 relative).
    """
    lo, hi, best = np.log(0.2), np.log(8.0), (float(y.mean()), 1e-9, 1.0, np.inf)
    for _ in range(4):
        gs = np.exp(np.linspace(lo, hi, 41))
        xg = x[None, :] ** gs[:, None]
        xm, ym = xg.mean(axis=1), y.mean()
        var = xg.var(axis=1)
        b = np.maximum(((xg - xm[:, None]) * (y - ym)).mean(axis=1) / np.maximum(var, 1e-30), 1e-9)
        a = ym - b * xm
        err = ((a[:, None] + b[:, None] * xg - y) ** 2).mean(axis=1)
        k = int(np.argmin(err))
        if err[k] < best[3]:
            best = (float(a[k]), float(b[k]), float(gs[k]), float(err[k]))
        step = (hi - lo) / 40
        lo, hi = np.log(gs[k]) - step, np.log(gs[k]) + step
    return best[0], best[1], best[2]


def decoupled_ramp_lut(
    ramp_colmeans: np.ndarray, w_tilde: np.ndarray, name: str, strict: bool = True
) -> np.ndarray:
    """rho: C~ = W~^-1 L_S regressed per level (Eq. 20). (W, 3) column means -> (256, 3)."""
    dec = ramp_colmeans @ np.linalg.inv(w_tilde).T
    return regress_rho(level_means(dec), name, strict)


# -- the calibration and its prediction at another eye (steps 3, 5, 6, 7) -------------------


@dataclass
class PaperCalibration:
    """What the paper's method keeps from the captures, to predict any eye.

    Means are (3,) linear; ``ramp_cols`` are per-column means of the real screen's ramp at 90
    (W, 3); ``n`` (3,) is Eq. 3's constant; ``fit`` the Phong fit; ``rho_w`` (256, 3).
    ``stat_mask`` (H, W) bool: the pixels the image-wide statistics (means, ramp columns,
    Eq. 10's change) are taken over (None: all), so that a highlight covering a few percent of
    the image, or clipped pixels, do not decide them.
    """

    geometry: ScreenGeometry
    n: np.ndarray
    fit: PhongFit
    means_c: dict[str, np.ndarray]
    ramp_cols_c: np.ndarray
    w_tilde_w: np.ndarray
    rho_w: np.ndarray
    rv90: np.ndarray
    stat_mask: np.ndarray | None = None
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    def delta_s(self, eye: np.ndarray, gain: np.ndarray) -> np.ndarray:
        """n i_c/i_s (S_theta - S_90) per pixel with the fitted model (Eq. 10): (H, W, 3)."""
        rv = self.geometry.rv(eye)
        return self.n * gain * (self.fit.predict(rv) - self.fit.predict(self.rv90))

    def _eye_terms(self, eye: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Column means (W, 3) and image mean (3,) of S_theta - S_90 at ``eye``, cached.

        Eq. 10's change is n i_c/i_s (S_theta - S_90): the gain and n are per-channel
        factors, so these means serve every feedback gain at one eye.
        """
        key = tuple(np.round(np.asarray(eye, float), 6))
        hit = self._cache.get(key)
        if hit is None:
            d = self.fit.predict(self.geometry.rv(eye)) - self.fit.predict(self.rv90)
            hit = (masked_column_means(d, self.stat_mask), masked_mean(d, self.stat_mask))
            self._cache[key] = hit
            if len(self._cache) > 256:
                self._cache.pop(next(iter(self._cache)))
        return hit

    def at_eye(self, eye: np.ndarray, gain: np.ndarray | None = None) -> tuple[np.ndarray, ...]:
        """W~_c and rho_c for the predicted calibration images at ``eye`` (steps 3-4).

        ``gain`` (3,) is i_c / i_s of the feedback (Eq. 25), 1 without it.
        """
        g = np.ones(3) if gain is None else np.asarray(gain, np.float64)
        cols, mean = self._eye_terms(eye)
        scale = self.n * g
        means = {k: v + scale * mean for k, v in self.means_c.items()}
        w_tilde = mixing_from_means(means, check_order=False)
        ramp = self.ramp_cols_c + scale * cols
        return w_tilde, decoupled_ramp_lut(ramp, w_tilde, "screen/ramp (predicted)", False)

    def runtime_model(self, eye: np.ndarray, gain: np.ndarray | None = None) -> RuntimeModel:
        """The paper method's runtime model at ``eye`` (global matrices and LUTs)."""
        w_tilde_c, rho_c = self.at_eye(eye, gain)
        inv, lo, hi = inverse_lut(rho_c)
        _h, _w = self.rv90.shape
        f32 = np.float32
        return RuntimeModel(
            method="paper",
            refl=self.geometry.refl.astype(f32),
            pos=self.geometry.pos.astype(f32),
            cam_eye=self.geometry.camera.astype(f32),
            fwd_lut=self.rho_w.astype(f32),
            inv_lut=inv.astype(f32),
            inv_lo=lo.astype(f32),
            inv_hi=hi.astype(f32),
            Ww=self.w_tilde_w.astype(f32),
            Wc_inv=np.linalg.inv(w_tilde_c).astype(f32),
        )


def calibrate_paper(
    white: dict[str, np.ndarray],
    screen: dict[str, np.ndarray],
    geometry: ScreenGeometry,
    fit_mode: str = "all",
    stat_mask: np.ndarray | None = None,
) -> PaperCalibration:
    """Steps 1, 2 and 4 of the paper on linearised captures (the rest happens per eye).

    Args:
        white, screen: pattern name -> (H, W, 3) linear captures on the projector grid.
        geometry: the rig's per-pixel geometry (same grid).
        fit_mode: "all" (Eq. 8) or "row" (Eq. 7).
        stat_mask: (H, W) bool, the pixels the pattern means and the ramp's columns are taken
            over (None: all); see :class:`PaperCalibration`.
    """
    rv90 = geometry.rv(geometry.camera)
    s90, n = specular_map(screen["gray"], white["gray"])
    fit = fit_phong(s90, rv90, fit_mode, camera_row(geometry))
    names = (*CHANNEL_PATTERNS, "gray")
    means_w = {k: masked_mean(white[k], stat_mask) for k in names}
    w_tilde_w = mixing_from_means(means_w)
    rho_w = decoupled_ramp_lut(
        masked_column_means(white["ramp"], stat_mask), w_tilde_w, "white/ramp"
    )
    means_c = {k: masked_mean(screen[k], stat_mask) for k in names}
    ramp_c = masked_column_means(screen["ramp"], stat_mask)
    # The captured ramp itself must make a response curve (checked here, strictly).
    decoupled_ramp_lut(ramp_c, mixing_from_means(means_c), "screen/ramp")
    return PaperCalibration(
        geometry=geometry,
        n=n,
        fit=fit,
        means_c=means_c,
        ramp_cols_c=ramp_c,
        w_tilde_w=w_tilde_w,
        rho_w=rho_w,
        rv90=rv90,
        stat_mask=stat_mask,
    )


def masked_mean(image: np.ndarray, mask: np.ndarray | None) -> np.ndarray:
    """Mean (3,) of an (H, W, 3) image over the pixels where ``mask`` (H, W) is True (all
    pixels for None)."""
    if mask is None:
        return image.reshape(-1, 3).mean(axis=0)
    return image[mask].mean(axis=0)


def masked_column_means(image: np.ndarray, mask: np.ndarray | None) -> np.ndarray:
    """Per-column means (W, 3) of an (H, W, 3) image over the rows where ``mask`` is True; a
    column with no such row takes the mean of its whole column."""
    if mask is None:
        return image.mean(axis=0)
    m = mask[..., None].astype(image.dtype)
    count = m.sum(axis=0)
    masked = (image * m).sum(axis=0) / np.maximum(count, 1)
    return np.where(count > 0, masked, image.mean(axis=0))
