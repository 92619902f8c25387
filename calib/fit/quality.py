"""How good the captures behind a calibration are: exposure, noise, clipping, and how well
the per-pixel model reproduces a capture it was not built from.

Measured by :func:`~viewcomp.calib.fit.calibrate.calibrate` on the captures on the projector
grid (after rectification for camera-space sets) and kept in the bundle's ``info``, so that
:mod:`viewcomp.calib.eval.verdict` can judge a calibration without its captures.
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np

from viewcomp.calib.fit.pixel import PixelCalibration
from viewcomp.calib.io.patterns import table1_patterns

#: Gaussian sigma (projector px) of the smooth part removed before measuring noise: wide
#: enough to keep vignetting and fall-off out of it, narrow enough to follow them.
NOISE_SIGMA_PX = 2.0
#: Median absolute deviation -> standard deviation for Gaussian noise.
MAD_TO_SIGMA = 1.4826
#: Fraction of the frame left out at each border (edges blur into the surround).
BORDER = 0.05
#: The summary numbers of :func:`capture_quality` read every STEP-th pixel along each axis:
#: a median and percentiles need no more, and a 4K frame's full maps would add hundreds of
#: MB of temporaries to calibrate's peak.
STEP = 4


def _interior(shape: tuple[int, ...]) -> tuple[slice, slice]:
    h, w = shape[:2]
    bh, bw = max(1, int(h * BORDER)), max(1, int(w * BORDER))
    return slice(bh, h - bh), slice(bw, w - bw)


def relative_noise(image: np.ndarray) -> np.ndarray:
    """Per channel (3,), the noise of a capture of a smooth scene relative to its level: the
    robust spread (MAD x 1.4826) of the image minus its Gaussian-smoothed self, over the
    median level, on the frame's interior. ``image``: (H, W, 3) linear; a uniform grey
    capture on the white screen is the intended input. The high-pass keeps about
    1 - 1/(4 pi sigma^2) of white noise's variance (0.98 at sigma 2): not corrected."""
    img = np.asarray(image, np.float32)
    smooth = cv2.GaussianBlur(img, (0, 0), NOISE_SIGMA_PX)
    inner = _interior(img.shape)
    resid = (img - smooth)[inner].reshape(-1, 3)
    level = np.median(img[inner].reshape(-1, 3), axis=0)
    spread = MAD_TO_SIGMA * np.median(np.abs(resid - np.median(resid, axis=0)), axis=0)
    return (spread / np.maximum(level, 1e-6)).astype(np.float64)


def full_output_level(pixel: PixelCalibration, step: int = 1) -> float:
    """The white screen at the projector's full output, in the capture's linear units (1 =
    the camera's full scale at the base exposure): 99th percentile over the frame (every
    ``step``-th pixel along each axis) of the channels' mean of W f(255) + A, f(255) = 1."""
    sub = (slice(None, None, step), slice(None, None, step))
    full = pixel.white.W[sub].sum(axis=-1) + pixel.white.A[sub]
    return float(np.percentile(full.mean(axis=-1), 99.0))


def ramp_residual(pixel: PixelCalibration, ramp: np.ndarray, step: int = 1) -> np.ndarray:
    """(H', W') float32: per pixel (every ``step``-th along each axis of the (H, W) grid), the
    per-pixel model's prediction of the real screen's ramp capture (the screen's mixing and
    ambient applied to the projector response fitted on the *white* screen's ramp) against
    the capture, |predicted - captured| over the pixel's level at the ramp's brightest, mean
    of the channels. Large where the model does not describe the pixel (noise, clipping, a
    response that differs across the screen)."""
    h, w = ramp.shape[:2]
    sub = (slice(None, None, step), slice(None, None, step))
    levels = table1_patterns(w, h)["ramp"][sub]
    f = pixel.f_lut
    drive = np.stack([f[levels[..., c], c] for c in range(3)], axis=-1).astype(np.float32)
    W, A = pixel.screen.W[sub], pixel.screen.A[sub]
    pred = np.einsum("hwij,hwj->hwi", W, drive) + A
    scale = W.sum(axis=-1) + A
    err = np.abs(pred - ramp[sub]) / np.maximum(scale, 1e-6)
    return err.mean(axis=-1).astype(np.float32)


def capture_quality(
    pixel: PixelCalibration, white: dict[str, np.ndarray], screen: dict[str, np.ndarray]
) -> dict[str, Any]:
    """The numbers :mod:`viewcomp.calib.eval.verdict` judges (JSON-ready): ``full_output``
    (:func:`full_output_level`), ``noise`` (3,) relative noise of the white screen's gray
    capture (:func:`relative_noise`), ``ramp_residual`` median and 95th percentile of
    :func:`ramp_residual` on the interior; the maps read every :data:`STEP`-th pixel."""
    resid = ramp_residual(pixel, screen["ramp"], STEP)
    resid = resid[_interior(resid.shape)]
    return {
        "full_output": round(full_output_level(pixel, STEP), 5),
        "noise": [round(float(v), 5) for v in relative_noise(white["gray"])],
        "ramp_residual_median": round(float(np.median(resid)), 5),
        "ramp_residual_p95": round(float(np.percentile(resid, 95.0)), 5),
    }
