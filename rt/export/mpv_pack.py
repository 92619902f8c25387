"""How `viewcomp export-mpv` (:mod:`viewcomp.rt.export.mpv`) stores per-pixel numbers as
mpv ``//!TEXTURE`` images: normalised 16- or 8-bit per texel channel over the grid, or
float32; the precision-8 split into a smooth base and a residual; the pixel method's maps."""

from __future__ import annotations

import cv2
import numpy as np

from viewcomp.calib.errors import ExportError
from viewcomp.calib.model.runtime import RuntimeModel
from viewcomp.calib.model.shader_inputs import pixel_texels

BASE_STEP = 4  # grid pixels per texel of the smooth base of a precision-8 export


def pack_images(
    texels: np.ndarray, precision: int = 16
) -> tuple[list[np.ndarray], np.ndarray, np.ndarray]:
    """Per-pixel texels (H, W, K, 4) as K (H, W, 4) images, image k = texel k of every pixel.

    ``precision`` 16: uint16 images and per texel channel (scale, offset), value = offset
    + t scale with t = q / 65535 the normalised texel (scale = max - min over the grid);
    32: float32 images with scale 1 and offset 0. Returns (images, scale (K, 4), offset
    (K, 4)).

    Raises:
        ExportError: a precision other than 16 or 32.
    """
    if precision not in (8, 16, 32):
        raise ExportError(f"precision is 8, 16 or 32 bits, got {precision}")
    k_n = texels.shape[2]
    scale = np.ones((k_n, 4), np.float64)
    offset = np.zeros((k_n, 4), np.float64)
    if precision == 32:
        images = [np.ascontiguousarray(texels[:, :, k], np.float32) for k in range(k_n)]
        return images, scale, offset
    top = float((1 << precision) - 1)
    images = []
    for k in range(k_n):
        f = texels[:, :, k].astype(np.float64)
        lo, hi = f.min(axis=(0, 1)), f.max(axis=(0, 1))
        span = hi - lo
        scale[k], offset[k] = span, lo
        q = np.rint((f - lo) / np.where(span > 0, span, 1.0) * top)
        images.append(np.clip(q, 0, top).astype(np.uint8 if precision == 8 else np.uint16))
    return images, scale, offset


def split_smooth(texels: np.ndarray, step: int = BASE_STEP) -> tuple[np.ndarray, np.ndarray]:
    """Per-pixel texels (H, W, K, 4) as a smooth base at 1/``step`` of the grid (area means,
    (ceil(H/step), ceil(W/step), K, 4)) and the residual (H, W, K, 4): texels = the base
    interpolated bilinearly at each pixel's centre (``cv2.resize`` INTER_LINEAR, edges
    clamped: what ``mpv_held.glsl``'s ``vc_base`` computes) + the residual. The residual
    spans far less than the texels, so 8 bits of it cost less than 16 of the texels."""
    h, w, k_n, _ = texels.shape
    flat = texels.reshape(h, w, k_n * 4).astype(np.float64)
    size = (-(-w // step), -(-h // step))
    base = cv2.resize(flat, size, interpolation=cv2.INTER_AREA).reshape(size[1], size[0], -1)
    up = cv2.resize(base, (w, h), interpolation=cv2.INTER_LINEAR).reshape(h, w, -1)
    return base.reshape(size[1], size[0], k_n, 4), (flat - up).reshape(h, w, k_n, 4)


def pack_maps(
    model: RuntimeModel, precision: int = 16
) -> tuple[list[np.ndarray], np.ndarray, np.ndarray]:
    """The pixel method's maps (:func:`~viewcomp.calib.model.shader_inputs.pixel_texels`) as 8
    images (:func:`pack_images`): what the eye-following (``//!PARAM``) hook reads.

    Raises:
        ExportError: a bad precision, or a model array that is missing, of the wrong shape
            or not finite.
    """
    try:
        texels = pixel_texels(model)
    except ValueError as exc:
        raise ExportError(f"the calibration's runtime model: {exc}") from None
    return pack_images(texels, precision)
