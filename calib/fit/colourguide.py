"""Edge-aware smoothing of the per-pixel colour terms (the colour mixing W~ and the shares of
the gains D), guided by the screen's own colour.

W~(x) (:func:`~viewcomp.calib.fit.pixel.mixing_tilde`) is a ratio of differences of captures
(a colour pattern minus gray, over its own channel): a camera's noise in it is amplified, and
its off-diagonal entries are small differences. Physically W~ is the product of the projector's
primaries, the camera's filters and the surface's reflectance spectrum: it changes across the
screen only where the surface's colour does. So each pattern's difference dL_j (the
numerator and denominator of W~'s column j) is smoothed over a large window wherever the
screen's colour is uniform, and follows the colour where it is not: a guided filter (He, Sun
and Tang, "Guided Image Filtering", 2013; :func:`guided_filter`) with the screen's
chromaticity as the guide - within each window, dL_j is regressed on the
chromaticity, so a colour edge keeps its step and a uniform region takes the window's mean.
W~ is then a ratio of these means, not a mean of ratios: a pixel whose own rise is small (a
channel the screen barely reflects) does not weigh more than its neighbours.

The guide is the gray capture's chromaticity, each channel over the pixel's mean of the three
(1, 1, 1 for a neutral colour; a highlight's white shows as its own colour), after a 1 px
Gaussian against the camera's noise. The filter runs in float64: OpenCV's
``ximgproc.guidedFilter`` sums in float32, which loses the small variance of a guide whose
values are near 1 (a colour guide with one channel 1 +- 0.01 and two constant: its slope
came out 0.003 where the closed form says 0.99, eps 1e-6).

Measured through ``viewcomp evaluate --protocol hardware``'s rows (320x160, 8 frames, seed 0;
mean dE of the compensated image over the ideal pipeline's at 60 / 125 degrees, before ->
with the guide): the emulated webcam in 8 bits on glossy magenta 1.10 / 1.08 -> 1.03 / 1.02,
orange phenolic 1.19 / 1.19 -> 1.12 / 1.13, spectralon 2.60 / 2.50 -> 1.57 / 1.55, green
plastic 1.16 / 1.16 -> 1.17 / 1.18; in HDR satin_gold 1.29 / 1.24 -> 1.13 / 1.11,
spectralon 3.13 / 2.96 -> 2.30 / 2.21 (docs/EVALUATION.md has every row). On the built-in
textured screen, whose colour edges it keeps (8 bits): 1.30 / 1.35 -> 1.16 / 1.19 with a
radius of 32 px, 1.19 / 1.23 with 16. The box windows leave a trace: a pixel far off its
neighbours (a camera's colour fringe along the frame's edge) shifts every window it is in,
seen as bands within a radius of the frame's edges on spectralon.

The same holds for the per-pixel gains D(x) (one per channel, from the gray capture): their
sum follows the surface's texture and is kept per pixel, but their shares of it are the
surface's colour, which changes where the chromaticity does; each channel's own noise makes
a colour noise in them that no lightness texture explains. :func:`smooth_shares` keeps the
sum and passes the shares through the same filter. A mono camera's three gains (one per
projector primary alone, docs/MODEL.md "Mono cameras") are three separate noisy captures and
gain most: its spectralon rows, 0.87 / 0.89 dE (8 bits, 60 / 125 degrees) against an ideal
mono camera's 0.64 / 0.68, become 0.62 / 0.65; a colour webcam's shares are smoothed already by
its demosaicking, denoising and chroma subsampling (spectralon 0.94 / 0.99 -> 0.90 / 0.95).
"""

from __future__ import annotations

from collections.abc import Callable

import cv2
import numpy as np

#: An image filter (H, W, C) -> (H, W, C) float32: what :func:`colour_smoother` returns.
Smoother = Callable[[np.ndarray], np.ndarray]

#: The guided filter's window radius (projector px): the window is 2 r + 1 pixels square.
GUIDE_RADIUS_PX = 32
#: Its regularisation (units of the guide's squared chromaticity): chromaticity changes
#: whose variance within a window is well above it (a change of about 3 %) are followed,
#: smaller ones averaged.
GUIDE_EPS = 1e-3
#: The Gaussian (projector px) the gray capture gets before its chromaticity is the guide.
GUIDE_SIGMA_PX = 1.0
#: The least share of a lit pixel's gains a channel keeps after smoothing: a channel the
#: screen barely reflects (a green screen's red) has a share within the noise of 0, which the
#: filter may take below it; the gains must stay positive for the model to be inverted.
SHARE_FLOOR = 1e-3


def guide_radius_for(space: str) -> int:
    """The guided filter's radius `calibrate` takes by default for a capture set in
    ``space``: :data:`GUIDE_RADIUS_PX` for "camera" (a real camera's noise, resampled onto
    the projector grid), 0 (none) for "projector" (captures already on the grid: the
    simulator's, whose evaluation figures are per pixel)."""
    return GUIDE_RADIUS_PX if space == "camera" else 0


def colour_guide(gray: np.ndarray) -> np.ndarray:
    """The screen's chromaticity (H, W, 3) float32 from its gray capture (H, W, 3) linear:
    each channel over the three's mean, after a :data:`GUIDE_SIGMA_PX` Gaussian against the
    camera's noise (1, 1, 1 where it is neutral or dark)."""
    g = np.asarray(gray, np.float32)
    if g.ndim != 3 or g.shape[-1] != 3:
        raise ValueError(f"gray must have shape (H, W, 3), got {g.shape}")
    g = np.asarray(cv2.GaussianBlur(g, (0, 0), GUIDE_SIGMA_PX, borderType=cv2.BORDER_REFLECT))
    mean = g.mean(axis=-1, keepdims=True)
    out = np.ones_like(g)
    lit = mean[..., 0] > 1e-6
    out[lit] = g[lit] / mean[lit]
    return out


def _box(img: np.ndarray, r: int) -> np.ndarray:
    """The mean over (2 r + 1)^2 windows of each channel of ``img`` (H, W[, C]) float64,
    mirrored at the borders."""
    out = cv2.boxFilter(img, cv2.CV_64F, (2 * r + 1, 2 * r + 1), borderType=cv2.BORDER_REFLECT)
    return np.asarray(out).reshape(img.shape)


class GuidedFilter:
    """He's guided filter with a colour guide (H, W, 3): per window of radius ``r``, an
    image regressed on the guide, the guide's 3x3 covariance regularised by ``eps`` I (units
    of the guide squared); each pixel takes the mean of its windows' fits. The guide's
    window statistics are computed once, for every image filtered with it.

    In float64 throughout: the guide's variance within a window is a small difference of
    large sums, which float32 loses when the guide varies little."""

    def __init__(self, guide: np.ndarray, r: int, eps: float) -> None:
        g = np.asarray(guide, np.float64)
        self.g = g - g.reshape(-1, 3).mean(axis=0)  # centred: the window sums stay small
        self.r = int(r)
        self.mg = _box(self.g, self.r)
        cov = np.empty((*g.shape[:2], 3, 3))
        for i in range(3):
            for j in range(i, 3):
                cov[..., i, j] = cov[..., j, i] = _box(self.g[..., i] * self.g[..., j], r) - (
                    self.mg[..., i] * self.mg[..., j]
                )
        cov += eps * np.eye(3)
        self.inv = np.linalg.inv(cov)  # (H, W, 3, 3)

    def __call__(self, src: np.ndarray) -> np.ndarray:
        """``src`` (H, W, C) filtered: (H, W, C) float64."""
        g, r = self.g, self.r
        p = np.asarray(src, np.float64)
        mp = _box(p, r)
        cov_gp = np.empty((*p.shape[:2], 3, p.shape[-1]))
        for i in range(3):
            cov_gp[..., i, :] = _box(g[..., i : i + 1] * p, r) - self.mg[..., i : i + 1] * mp
        a = np.einsum("hwij,hwjc->hwic", self.inv, cov_gp)  # (H, W, 3, C)
        del cov_gp
        b = mp - np.einsum("hwic,hwi->hwc", a, self.mg)
        ma = _box(a.reshape(*a.shape[:2], -1), r).reshape(a.shape)
        return np.asarray(np.einsum("hwic,hwi->hwc", ma, g) + _box(b, r))


def guided_filter(guide: np.ndarray, src: np.ndarray, r: int, eps: float) -> np.ndarray:
    """``src`` (H, W, C) through :class:`GuidedFilter` of ``guide`` (H, W, 3): (H, W, C)
    float64."""
    return GuidedFilter(guide, r, eps)(src)


def colour_smoother(
    gray: np.ndarray, radius: int | None = None, eps: float | None = None
) -> Smoother:
    """The guided filter of images (H, W, C) by the screen's chromaticity
    (:func:`colour_guide` of its gray capture (H, W, 3) linear), returning float32:
    ``radius`` (projector px, >= 0; None: :data:`GUIDE_RADIUS_PX`; 0: images as they are)
    and ``eps`` (None: :data:`GUIDE_EPS`)."""
    r = GUIDE_RADIUS_PX if radius is None else int(radius)
    if r < 0:
        raise ValueError(f"radius must be >= 0, got {r}")
    h, w = np.shape(gray)[:2]
    r = min(r, (min(h, w) - 1) // 2)
    if r <= 0:
        return lambda img: np.ascontiguousarray(img, np.float32)
    flt = GuidedFilter(colour_guide(gray), r, GUIDE_EPS if eps is None else float(eps))
    return lambda img: np.asarray(flt(img), np.float32)


def smooth_shares(gains: np.ndarray, smooth: Smoother) -> np.ndarray:
    """Per-pixel gains (H, W, 3) with their sum over the channels kept per pixel and their
    shares of it (each channel over the sum) passed through ``smooth`` (a
    :func:`colour_smoother`), floored at :data:`SHARE_FLOOR` and renormalised to sum to 1:
    (H, W, 3) float32, every gain of a lit pixel > 0. Pixels whose sum is not positive are
    returned as they are."""
    d = np.asarray(gains, np.float32)
    total = d.sum(axis=-1, keepdims=True)
    lit = total[..., 0] > 0
    shares = np.where(lit[..., None], d / np.where(lit[..., None], total, 1.0), 1.0 / 3.0)
    shares = np.maximum(smooth(shares), SHARE_FLOOR)
    out = total * shares / shares.sum(axis=-1, keepdims=True)
    return np.where(lit[..., None], out, d).astype(np.float32)
