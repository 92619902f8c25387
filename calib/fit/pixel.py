"""The per-pixel method (docs/MODEL.md section 4).

Per pixel x and for each screen (white ``w``, real ``c``), Grossberg's model with a full 3x3
colour-mixing matrix and ambient:

    L(x; I) = W(x) f(I) + A(x),      W(x) = W~(x) diag(D(x))

where f is the projector's response (per channel, global: a property of the projector,
normalised to f(0) = 0, f(255) = 1), W~(x) the colour mixing from per-pixel differences of
the red/green/blue patterns against gray (smoothed), D(x) the per-pixel gain from the gray
pattern, A(x) the black capture (or an estimate without one).

The specular lobe is fitted as a diffuse baseline plus a lobe relative to the white screen,
s(x) = (L_c,U - A_c) / (L_w,U - A_w) = b + kappa (R.V)^gamma, by non-linear least squares;
its change with the eye scales with each pixel's own projected light:

    L_c(x; I, eye) = L_c(x; I, cam) + diag(ds(x)) W_w(x) f(I),
    ds(x) = kappa ((R.V_eye)^gamma - (R.V_cam)^gamma)

so the compensation at any eye is one per-pixel linear solve (docs/RUNTIME.md): the fixed
point of the feedback I <- F_c^-1(T - ds F_w(I)) reached exactly, since F_c and F_w share f.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter
from scipy.optimize import least_squares

from viewcomp.calib.errors import FitError
from viewcomp.calib.fit.paper import (
    CHANNEL_PATTERNS,
    inverse_lut,
    level_means,
    monotone_lut,
)
from viewcomp.calib.io.patterns import GRAY_LEVEL
from viewcomp.calib.model.runtime import RuntimeModel
from viewcomp.calib.world.geometry import ScreenGeometry

DEFAULT_SMOOTH_PX = 3.0


@dataclass(frozen=True)
class ScreenModel:
    """One screen's per-pixel model: W (H, W, 3, 3) and A (H, W, 3), linear camera units."""

    W: np.ndarray
    A: np.ndarray
    ambient_measured: bool


@dataclass(frozen=True)
class LobeFit:
    """s = b + kappa (R.V)^gamma per channel, with its residual, and the pure power law's.

    ``rms``: RMS residual of this fit (units of s); ``rms_power_law``: RMS residual of the
    paper's log s = a + gamma log(R.V) fitted to the same samples, in the same units.
    """

    baseline: np.ndarray  # (3,)
    kappa: np.ndarray  # (3,)
    gamma: float
    rms: np.ndarray  # (3,)
    rms_power_law: np.ndarray  # (3,)
    samples: int
    message: str

    def sigma(self, rv: np.ndarray) -> np.ndarray:
        """The lobe kappa max(R.V, 0)^gamma: (H, W) -> (H, W, 3)."""
        return self.kappa * np.maximum(rv, 0.0)[..., None] ** self.gamma


@dataclass
class PixelCalibration:
    """Everything the per-pixel method needs: f, both screens' models, the lobe, geometry."""

    geometry: ScreenGeometry
    f_lut: np.ndarray  # (256, 3), f(0) ~ 0, f(255) = 1
    white: ScreenModel
    screen: ScreenModel
    lobe: LobeFit
    response_rms: float

    def runtime_model(self) -> RuntimeModel:
        """The per-pixel runtime model (docs/RUNTIME.md); the eye is a per-frame uniform."""
        inv, lo, hi = inverse_lut(self.f_lut)
        f32 = np.float32
        return RuntimeModel(
            method="pixel",
            refl=self.geometry.refl.astype(f32),
            pos=self.geometry.pos.astype(f32),
            cam_eye=self.geometry.camera.astype(f32),
            fwd_lut=self.f_lut.astype(f32),
            inv_lut=inv.astype(f32),
            inv_lo=lo.astype(f32),
            inv_hi=hi.astype(f32),
            Ww=self.white.W.astype(f32),
            Aw=self.white.A.astype(f32),
            Wc=self.screen.W.astype(f32),
            Ac=self.screen.A.astype(f32),
            kappa=self.lobe.kappa.astype(f32),
            gamma=float(self.lobe.gamma),
        )


def _smooth(img: np.ndarray, sigma: float) -> np.ndarray:
    if sigma <= 0:
        return img
    return gaussian_filter(img, sigma=(sigma, sigma, 0), mode="nearest")


def mixing_tilde(caps: dict[str, np.ndarray], sigma: float, sub: str) -> np.ndarray:
    """Per-pixel W~(x) (H, W, 3, 3) from smoothed dL_j(x) = L_j(x) - L_U(x) (Eq. 16 per pixel).

    Raises:
        FitError: a colour pattern is not brighter than gray in its own channel somewhere.
    """
    h, w, _ = caps["gray"].shape
    wt = np.empty((h, w, 3, 3))
    for j, name in enumerate(CHANNEL_PATTERNS):
        d = _smooth(caps[name] - caps["gray"], sigma)
        own = d[..., j]
        bad = own <= 1e-5
        if np.mean(bad) > 0.01:
            raise FitError(
                f"{sub}/{name}",
                f"not brighter than {sub}/gray in its own channel over {np.mean(bad):.0%} of "
                "the image: patterns in the wrong order, or the camera's white balance moved",
            )
        own = np.maximum(own, 1e-5)
        wt[..., :, j] = d / own[..., None]
    return wt


def _estimate_ambient(caps: dict[str, np.ndarray], sigma: float) -> tuple[np.ndarray, bool]:
    """A(x): the black capture, or an estimate from the ramp's dark end without one.

    Without a black capture, the columns of the ramp at level 0 see (ambient + projector
    leak); that colour, spread over the image in proportion to the gray capture (albedo and
    vignetting), is the estimate.
    """
    if "black" in caps:
        return _smooth(caps["black"], sigma), True
    ramp = caps["ramp"]
    dark = ramp[:, :2].reshape(-1, 3).mean(axis=0)
    gray = caps["gray"]
    ratio = gray / np.maximum(gray[:, :2].reshape(-1, 3).mean(axis=0), 1e-6)
    return _smooth(dark * ratio, sigma), False


def projector_response(white: dict[str, np.ndarray], wt: np.ndarray, amb: np.ndarray) -> tuple:
    """f per channel from the white screen's ramp, normalised per pixel by the gray capture.

    r(x) = [W~^-1 (L_S - A)] / [W~^-1 (L_U - A)] = f(I(u)) / f(110) removes every spatial
    effect (vignetting, fall-off), leaving the response's shape, regressed monotone.

    Returns:
        (f_lut (256, 3) with f(255) = 1, RMS misfit of the per-level samples (units of f)).
    """
    inv = np.linalg.inv(wt)
    num = np.einsum("hwij,hwj->hwi", inv, white["ramp"] - amb)
    den = np.einsum("hwij,hwj->hwi", inv, white["gray"] - amb)
    r = num / np.maximum(den, 1e-6)
    samples = level_means(np.median(r, axis=0))
    lut = monotone_lut(samples, "white/ramp")
    lut = np.maximum(lut - min(0.0, float(lut[0].min())), 0.0)
    top = lut[-1].copy()
    lut /= top
    misfit = float(np.sqrt(np.mean((samples / top - lut) ** 2)))
    return lut, misfit


def screen_model(
    caps: dict[str, np.ndarray], f_lut: np.ndarray, sigma: float, sub: str
) -> ScreenModel:
    """W(x) = W~(x) diag(D(x)), D from the gray capture, A from black (or estimated)."""
    wt = mixing_tilde(caps, sigma, sub)
    amb, measured = _estimate_ambient(caps, sigma)
    dec = np.einsum("hwij,hwj->hwi", np.linalg.inv(wt), caps["gray"] - amb)
    f110 = np.array([np.interp(GRAY_LEVEL, np.arange(256), f_lut[:, c]) for c in range(3)])
    d = dec / f110
    if np.mean(d <= 0) > 0.01:
        raise FitError(
            f"{sub}/gray",
            "darker than the black level over much of the image: is black.png really the "
            "black pattern, and did the ambient light change between captures?",
        )
    return ScreenModel(W=wt * d[..., None, :], A=amb, ambient_measured=measured)


def fit_lobe(s: np.ndarray, rv: np.ndarray, step: int = 2) -> LobeFit:
    """Fit s = b + kappa (R.V)^gamma (b, kappa per channel, one gamma) by least squares.

    Args:
        s: (H, W, 3) specular ratio of the real to the white screen (ambient removed).
        rv: (H, W) R.V toward the calibration camera.
        step: subsampling of the pixels used.

    Returns:
        LobeFit; ``kappa = 0`` and a message when the screen shows no lobe (matte).
    """
    ok = rv[::step, ::step] > 0
    x = np.maximum(rv[::step, ::step][ok], 1e-9)
    y = s[::step, ::step][ok]
    if x.size < 20:
        raise FitError("screen/gray", "too few pixels with R.V > 0 to fit the specular lobe")
    lx = np.log(x)

    def model(p: np.ndarray) -> np.ndarray:
        return p[0:3] + p[3:6] * np.exp(p[6] * lx)[:, None]

    def resid(p: np.ndarray) -> np.ndarray:
        return (model(p) - y).ravel()

    b0 = np.percentile(y, 5, axis=0)
    k0 = np.maximum(np.percentile(y, 99.5, axis=0) - b0, 1e-3)
    best = None
    for g0 in (5.0, 20.0, 80.0):
        p0 = np.concatenate([b0, k0, [g0]])
        r = least_squares(
            resid, p0, bounds=([0] * 6 + [0.5], [np.inf] * 6 + [5000.0]), x_scale="jac"
        )
        if best is None or r.cost < best.cost:
            best = r
    p = best.x
    rms = np.sqrt(np.mean((model(p) - y) ** 2, axis=0))
    # The paper's pure power law on the same samples, for comparison (rms in units of s).
    design = np.stack([np.ones_like(lx), lx], axis=1)
    pl = np.empty(3)
    for ch in range(3):
        coef, *_ = np.linalg.lstsq(design, np.log(np.maximum(y[:, ch], 1e-9)), rcond=None)
        pl[ch] = np.sqrt(np.mean((np.exp(design @ coef) - y[:, ch]) ** 2))
    kappa, gamma = p[3:6], float(p[6])
    noise = np.std(y - model(p), axis=0)
    message = "baseline + lobe fitted"
    if np.all(kappa < 2 * noise + 1e-3):
        kappa = np.zeros(3)
        gamma = 1.0
        message = "no specular lobe above the noise: treated as matte"
    return LobeFit(p[0:3], kappa, gamma, rms, pl, int(x.size), message)


def calibrate_pixel(
    white: dict[str, np.ndarray],
    screen: dict[str, np.ndarray],
    geometry: ScreenGeometry,
    smooth_px: float = DEFAULT_SMOOTH_PX,
) -> PixelCalibration:
    """Build the per-pixel calibration from linearised captures on the projector grid.

    Args:
        white, screen: pattern name -> (H, W, 3) linear captures (``black`` optional, in both
            or in neither).
        geometry: the rig's per-pixel geometry on the same grid.
        smooth_px: Gaussian sigma (projector pixels) for the colour-mixing ratios and ambient.
    """
    wt_w = mixing_tilde(white, smooth_px, "white")
    amb_w, _ = _estimate_ambient(white, smooth_px)
    f_lut, misfit = projector_response(white, wt_w, amb_w)
    wm = screen_model(white, f_lut, smooth_px, "white")
    cm = screen_model(screen, f_lut, smooth_px, "screen")
    s = (screen["gray"] - cm.A) / np.maximum(white["gray"] - wm.A, 1e-6)
    lobe = fit_lobe(s, geometry.rv(geometry.camera))
    return PixelCalibration(geometry, f_lut, wm, cm, lobe, misfit)
