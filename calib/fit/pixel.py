"""The per-pixel method (docs/MODEL.md section 4).

Per pixel x and for each screen (white ``w``, real ``c``), Grossberg's model with a full 3x3
colour-mixing matrix and ambient:

    L(x; I) = W(x) f(I) + A(x),      W(x) = W~(x) diag(D(x))

where f is the projector's response (per channel, global: a property of the projector,
normalised to f(0) = 0, f(255) = 1), W~(x) the colour mixing from per-pixel differences of
the red/green/blue patterns against gray (smoothed, and smoothed further where the screen's
colour is uniform: :mod:`~viewcomp.calib.fit.colourguide`), D(x) the per-pixel gain from the gray
pattern, A(x) the black capture (or an estimate without one).

The specular lobe is fitted as a diffuse baseline plus a tabulated lobe relative to the white
screen, s(x) = (L_c,U - A_c) / (L_w,U - A_w) = b + lobe(t(x)) (:mod:`viewcomp.calib.fit.lobe`);
its change with the eye scales with each pixel's own projected light, and with the share
eta of the black level that is projector light (its black leak, measured from the black
capture's highlight; :func:`~viewcomp.calib.fit.lobe.black_lobe_share`):

    L_c(x; I, eye) = L_c(x; I, cam) + diag(ds(x)) (W_w(x) f(I) + eta A_w(x)),
    ds(x) = lobe(t_eye(x)) - lobe(t_cam(x))

so the compensation at any eye is one per-pixel linear solve (docs/RUNTIME.md): the fixed
point of the feedback I <- F_c^-1(T - ds F_w(I)) reached exactly, since F_c and F_w share f.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from viewcomp.calib.errors import FitError
from viewcomp.calib.fit.colourguide import Smoother, colour_smoother, smooth_shares
from viewcomp.calib.fit.lobe import LobeFit, black_lobe_share, fit_lobe
from viewcomp.calib.fit.paper import (
    CHANNEL_PATTERNS,
    inverse_lut,
    level_means,
    mixing_from_means,
    monotone_lut,
)
from viewcomp.calib.io.patterns import GRAY_LEVEL
from viewcomp.calib.model.runtime import RuntimeModel
from viewcomp.calib.world.geometry import ScreenGeometry

DEFAULT_SMOOTH_PX = 3.0
#: A real screen's per-pixel gain D in a channel it barely reflects is floored at this share of
#: its largest channel's median gain.
_GAIN_FLOOR = 1e-3
#: A colour pattern darker than gray in its own channel by more than this share of the
#: image's median rise there, and by more than _NOISE_SIGMAS times the rise's robust spread, is
#: out of order. Noise on a channel the screen barely reflects stays within it: a webcam's
#: blue on orange phenolic falls below -0.5 of its median on 2.5 % of the pixels, below the
#: spread's bound on none.
_DARKER = 0.5
_NOISE_SIGMAS = 3.0
#: Median gain below -this (units of f(110)): the gray capture is systematically below black.
_DARK_NOISE = 0.01


@dataclass(frozen=True)
class ScreenModel:
    """One screen's per-pixel model: W (H, W, 3, 3) and A (H, W, 3), float32 linear camera
    units (the precision the bundle and the runtime keep; the fits' sums run in float64)."""

    W: np.ndarray
    A: np.ndarray
    ambient_measured: bool


@dataclass
class PixelCalibration:
    """Everything the per-pixel method needs: f, both screens' models, the lobe, geometry."""

    geometry: ScreenGeometry
    f_lut: np.ndarray  # (256, 3), f(0) ~ 0, f(255) = 1
    white: ScreenModel
    screen: ScreenModel
    lobe: LobeFit
    response_rms: float
    black_share: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def runtime_model(self) -> RuntimeModel:
        """The per-pixel runtime model (docs/RUNTIME.md); the eye is a per-frame uniform."""
        inv, lo, hi = inverse_lut(self.f_lut)
        f32 = np.float32

        def share(a: np.ndarray) -> np.ndarray:
            """The float32 maps themselves, read-only (no copy: 200 MB at 1080p)."""
            out = np.asarray(a, f32)
            if out is a:
                out = out.view()
                out.flags.writeable = False
            return out

        return RuntimeModel(
            method="pixel",
            refl=self.geometry.refl.astype(f32),
            pos=self.geometry.pos.astype(f32),
            cam_eye=self.geometry.camera.astype(f32),
            fwd_lut=self.f_lut.astype(f32),
            inv_lut=inv.astype(f32),
            inv_lo=lo.astype(f32),
            inv_hi=hi.astype(f32),
            Ww=share(self.white.W),
            Aw=share(self.white.A),
            Wc=share(self.screen.W),
            Ac=share(self.screen.A),
            lobe=self.lobe.table.astype(f32),
            lobe_half=self.lobe.half,
            lobe_black=self.black_share.astype(f32),
        )


#: Pixels per block of rows in the per-pixel 3x3 algebra: bounds its float64 temporaries to
#: tens of MB whatever the grid (a 3840x2160 grid is 8.3 M pixels).
BLOCK_PIXELS = 1 << 18


def row_blocks(h: int, w: int) -> list[slice]:
    """Slices of rows of an (h, w) grid, each about :data:`BLOCK_PIXELS` pixels."""
    step = max(1, BLOCK_PIXELS // max(w, 1))
    return [slice(r, min(h, r + step)) for r in range(0, h, step)]


def decouple(wt: np.ndarray, x: np.ndarray, minus: np.ndarray) -> np.ndarray:
    """W~(x)^-1 (x - minus) per pixel: (H, W, 3) float32 from wt (H, W, 3, 3) and x, minus
    (H, W, 3), inverted in float64 one block of rows at a time (no full-grid temporaries)."""
    out = np.empty(x.shape, np.float32)
    for rows in row_blocks(*x.shape[:2]):
        inv = np.linalg.inv(wt[rows].astype(np.float64))
        out[rows] = np.einsum("hwij,hwj->hwi", inv, x[rows] - minus[rows])
    return out


def _smooth(img: np.ndarray, sigma: float) -> np.ndarray:
    """Gaussian blur over the grid (not across channels), float32 out."""
    from scipy.ndimage import gaussian_filter  # imported when fitting: loading is faster

    img = np.asarray(img, np.float32)
    if sigma <= 0:
        return img
    return gaussian_filter(img, sigma=(sigma, sigma, 0), mode="nearest")


def mixing_tilde(
    caps: dict[str, np.ndarray], sigma: float, sub: str, smooth: Smoother | None = None
) -> np.ndarray:
    """Per-pixel W~(x) (H, W, 3, 3) from smoothed dL_j(x) = L_j(x) - L_U(x) (Eq. 16 per pixel),
    each dL_j smoothed further where the screen's colour is uniform by ``smooth`` (a
    :func:`~viewcomp.calib.fit.colourguide.colour_smoother` of ``caps["gray"]``; None, the
    default: not) before its ratio is taken: a ratio of window means, not a mean of ratios, so
    a pixel whose own rise is small does not weigh more.

    Raises:
        FitError: a colour pattern clearly darker than gray in its own channel over more than
            1 % of the image (:data:`_DARKER`, :data:`_NOISE_SIGMAS`), or not brighter on
            average.
    """
    h, w, _ = caps["gray"].shape
    # The image means must show each pattern raising its own channel most (the paper's order
    # check, Eq. 16): otherwise the captures are swapped.
    try:
        mixing_from_means(
            {k: caps[k].reshape(-1, 3).mean(axis=0) for k in (*CHANNEL_PATTERNS, "gray")}
        )
    except FitError as exc:
        raise FitError(f"{sub}/{exc.capture}", exc.reason) from None
    wt = np.empty((h, w, 3, 3), np.float32)
    for j, name in enumerate(CHANNEL_PATTERNS):
        d = _smooth(caps[name] - caps["gray"], sigma)
        own = d[..., j]
        typical = float(np.median(own))
        spread = 1.4826 * float(np.median(np.abs(own - typical)))  # the noise's sigma, robust
        darker = own < -max(_DARKER * typical, _NOISE_SIGMAS * spread)
        if np.mean(darker) > 0.01:
            raise FitError(
                f"{sub}/{name}",
                f"darker than {sub}/gray in its own channel over {np.mean(darker):.0%} of "
                "the image: patterns in the wrong order, or the camera's white balance moved",
            )
        if smooth is not None:
            d = smooth(d)
            own = d[..., j]
        # A channel the screen barely reflects (a green screen's red) leaves its pattern's
        # rise within the camera's noise at some pixels: no mixing is measured there, so they
        # take the image's median mixing of that pattern instead of a ratio to noise.
        unknown = own <= 1e-5
        col = d / np.maximum(own, 1e-5)[..., None]
        if unknown.any():
            col[unknown] = np.median(col[~unknown], axis=0) if (~unknown).any() else 0.0
            col[unknown, j] = 1.0
        wt[..., :, j] = col
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
    r = decouple(wt, white["ramp"], amb)
    r /= np.maximum(decouple(wt, white["gray"], amb), 1e-6)
    samples = level_means(np.median(r, axis=0).astype(np.float64))
    lut = monotone_lut(samples, "white/ramp")
    lut = np.maximum(lut - min(0.0, float(lut[0].min())), 0.0)
    top = lut[-1].copy()
    lut /= top
    misfit = float(np.sqrt(np.mean((samples / top - lut) ** 2)))
    return lut, misfit


def screen_model(
    caps: dict[str, np.ndarray],
    f_lut: np.ndarray,
    sigma: float,
    sub: str,
    wt: np.ndarray | None = None,
    smooth: Smoother | None = None,
) -> ScreenModel:
    """W(x) = W~(x) diag(D(x)), D from the gray capture, A from black (or estimated);
    ``smooth``: :func:`mixing_tilde`'s, and with it D's shares of their per-pixel sum are
    smoothed by the same guide (:func:`~viewcomp.calib.fit.colourguide.smooth_shares`: the
    sum keeps the texture, the shares are the surface's colour). ``wt``: this screen's W~
    when already fitted (it becomes W in place), else fitted here."""
    if wt is None:
        wt = mixing_tilde(caps, sigma, sub, smooth)
    amb, measured = _estimate_ambient(caps, sigma)
    f110 = np.array([np.interp(GRAY_LEVEL, np.arange(256), f_lut[:, c]) for c in range(3)])
    d = decouple(wt, caps["gray"], amb) / f110.astype(np.float32)
    if smooth is not None:
        d = smooth_shares(d, smooth)
    if np.mean(d <= 0) > 0.01:
        if sub == "white" or np.any(np.median(d, axis=(0, 1)) < -_DARK_NOISE):
            raise FitError(
                f"{sub}/gray",
                "darker than the black level over much of the image: is black.png really the "
                "black pattern, and did the ambient light change between captures?",
            )
        # A real screen that reflects (almost) nothing in a channel, at an exposure set for
        # its highlight: its gain there is the noise about 0. A small floor keeps the model
        # invertible; the tone map then treats that channel as the dark one it is.
        d = np.maximum(d, np.float32(_GAIN_FLOOR * float(np.max(np.median(d, axis=(0, 1))))))
    wt *= d[..., None, :]  # W = W~ diag(D), in place: one (H, W, 3, 3) array at a time
    return ScreenModel(W=wt, A=amb, ambient_measured=measured)


def calibrate_pixel(
    white: dict[str, np.ndarray],
    screen: dict[str, np.ndarray],
    geometry: ScreenGeometry,
    smooth_px: float = DEFAULT_SMOOTH_PX,
    valid: np.ndarray | None = None,
    lobe_param: str | None = None,
    guide_px: int = 0,
    filled: np.ndarray | None = None,
) -> PixelCalibration:
    """Build the per-pixel calibration from linearised captures on the projector grid.

    Args:
        white, screen: pattern name -> (H, W, 3) linear captures (``black`` optional, in both
            or in neither).
        geometry: the rig's per-pixel geometry on the same grid.
        smooth_px: Gaussian sigma (projector pixels) for the colour-mixing ratios and ambient.
        valid: (H, W) bool, pixels the lobe fit may use (False: clipped in some capture).
        lobe_param: force the lobe's parametrisation ("half" or "mirror"); None: the better.
        guide_px: the colour mixing, and the gains' shares of their sum, also smoothed where
            the screen's colour is uniform, over windows of this radius (projector px; 0:
            not; :mod:`~.colourguide`).
        filled: (H, W) bool, the pixels that hold copies, not measurements (the frame's
            edge zone of a camera-space set): :func:`~viewcomp.calib.fit.lobe.fit_lobe`'s.
    """
    smooth_w = colour_smoother(white["gray"], guide_px) if guide_px else None
    wt_w = mixing_tilde(white, smooth_px, "white", smooth_w)
    amb_w, _ = _estimate_ambient(white, smooth_px)
    f_lut, misfit = projector_response(white, wt_w, amb_w)
    del amb_w
    wm = screen_model(white, f_lut, smooth_px, "white", wt_w, smooth_w)  # W~ becomes W
    del wt_w, smooth_w
    smooth_s = colour_smoother(screen["gray"], guide_px) if guide_px else None
    cm = screen_model(screen, f_lut, smooth_px, "screen", smooth=smooth_s)
    del smooth_s
    s = (screen["gray"] - cm.A) / np.maximum(white["gray"] - wm.A, 1e-6)
    lobe = fit_lobe(s, geometry, valid, lobe_param, filled=filled)
    share = np.zeros(3)
    if "black" in screen and "black" in white:
        ratio = cm.A / np.maximum(wm.A, 1e-6)
        ok = np.ones(s.shape[:2], bool) if valid is None else valid
        share = black_lobe_share(ratio, lobe.at(geometry, geometry.camera), lobe.baseline, ok)
    return PixelCalibration(geometry, f_lut, wm, cm, lobe, misfit, share)
