"""Edge-aware smoothing of the per-pixel colour mixing W~, guided by the screen's own colour.

W~(x) (:func:`~viewcomp.calib.fit.pixel.mixing_tilde`) is a ratio of differences of captures
(a colour pattern minus gray, over its own channel): a camera's noise in it is amplified, and
its off-diagonal entries are small differences. Physically W~ is the product of the projector's
primaries, the camera's filters and the surface's reflectance spectrum: it changes across the
screen only where the surface's colour does. So each pattern's difference dL_j (the
numerator and denominator of W~'s column j) is smoothed over a large window wherever the
screen's colour is uniform, and follows the colour where it is not: a guided filter (He, Sun
and Tang, "Guided Image Filtering", 2013; OpenCV's ``ximgproc.guidedFilter``) with the
screen's chromaticity as the guide - within each window, dL_j is regressed on the
chromaticity, so a colour edge keeps its step and a uniform region takes the window's mean.
W~ is then a ratio of these means, not a mean of ratios: a pixel whose own rise is small (a
channel the screen barely reflects) does not weigh more than its neighbours.

The guide is the gray capture's chromaticity, each channel over the pixel's mean of the three
(1, 1, 1 for a neutral colour; a highlight's white shows as its own colour), after a 1 px
Gaussian against the camera's noise; a channel whose chromaticity is noisier than
:data:`SPREAD_FLOOR` (a channel the screen barely reflects) weighs less in it
(:func:`colour_guide`).

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
"""

from __future__ import annotations

import cv2
import numpy as np

#: The guided filter's window radius (projector px): the window is 2 r + 1 pixels square.
GUIDE_RADIUS_PX = 32
#: Its regularisation, in the guide's units (:func:`colour_guide`): chromaticity changes
#: whose variance within a window is well above GUIDE_EPS x SPREAD_FLOOR^2 (1e-3: a change of
#: about 3 %) are followed, smaller ones averaged.
GUIDE_EPS = 10.0
#: The chromaticity noise (per channel) below which a guide channel keeps its own units.
SPREAD_FLOOR = 0.01
#: The Gaussian (projector px) the gray capture gets before its chromaticity is the guide.
GUIDE_SIGMA_PX = 1.0


def guide_radius_for(space: str) -> int:
    """The guided filter's radius `calibrate` takes by default for a capture set in
    ``space``: :data:`GUIDE_RADIUS_PX` for "camera" (a real camera's noise, resampled onto
    the projector grid), 0 (none) for "projector" (captures already on the grid: the
    simulator's, whose evaluation figures are per pixel)."""
    return GUIDE_RADIUS_PX if space == "camera" else 0


def chroma_noise(chroma: np.ndarray) -> np.ndarray:
    """The noise of a chromaticity image (H, W, 3) per channel (3,): the robust spread
    (1.4826 x the median absolute deviation) of each pixel about its 3x3 mean, which a
    uniform region holds only the noise of and a colour edge touches few pixels of."""
    local = chroma - cv2.blur(chroma, (3, 3), borderType=cv2.BORDER_REFLECT)
    dev = np.abs(local - np.median(local, axis=(0, 1)))
    return np.asarray(1.4826 * np.median(dev, axis=(0, 1)), np.float64)


def colour_guide(gray: np.ndarray) -> np.ndarray:
    """The guide (H, W, 3) float32 from a screen's gray capture (H, W, 3) linear: its
    chromaticity (each channel over the three's mean, 1 where it is neutral or dark, after a
    :data:`GUIDE_SIGMA_PX` Gaussian), each channel over the larger of its noise
    (:func:`chroma_noise`) and :data:`SPREAD_FLOOR`. A channel the camera sees well keeps
    the chromaticity's own units (in which :data:`GUIDE_EPS` x SPREAD_FLOOR^2 is the
    variance that separates noise from colour); a dim channel whose chromaticity is noisier
    weighs less, as the gray capture's noise is also in the differences the guide steers,
    and a guide that followed it would put it back."""
    g = np.asarray(gray, np.float32)
    if g.ndim != 3 or g.shape[-1] != 3:
        raise ValueError(f"gray must have shape (H, W, 3), got {g.shape}")
    g = np.asarray(cv2.GaussianBlur(g, (0, 0), GUIDE_SIGMA_PX, borderType=cv2.BORDER_REFLECT))
    mean = g.mean(axis=-1, keepdims=True)
    out = np.ones_like(g)
    lit = mean[..., 0] > 1e-6
    out[lit] = g[lit] / mean[lit]
    spread = np.maximum(chroma_noise(out), SPREAD_FLOOR)
    return np.asarray(out / spread.astype(np.float32), np.float32)


def smooth_by_colour(
    img: np.ndarray, guide: np.ndarray, radius: int | None = None, eps: float | None = None
) -> np.ndarray:
    """The guided filter of ``img`` (H, W, C) float by ``guide`` (H, W, 3) from
    :func:`colour_guide`: (H, W, C) float32. ``radius`` (projector px, >= 0; None:
    :data:`GUIDE_RADIUS_PX`; 0: ``img`` as it is) and ``eps`` (None: :data:`GUIDE_EPS`)."""
    r = GUIDE_RADIUS_PX if radius is None else int(radius)
    if r < 0:
        raise ValueError(f"radius must be >= 0, got {r}")
    out = np.ascontiguousarray(img, np.float32)
    h, w = out.shape[:2]
    r = min(r, (min(h, w) - 1) // 2)
    if r <= 0:
        return out
    e = GUIDE_EPS if eps is None else float(eps)
    # the ximgproc stubs list only the UMat overload; the function takes arrays
    smooth = cv2.ximgproc.guidedFilter(guide, out, r, e, -1)  # type: ignore[call-overload]
    return np.asarray(smooth, np.float32)
