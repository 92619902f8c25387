"""The camera's response estimated from an HDR bracket, for `capture --hdr` without a known
response: OpenCV's ``createCalibrateDebevec`` (Debevec and Malik 1997) recovers the curve
code -> relative light from 8-bit frames of one scene at known relative exposures; the
rig.toml value written is the simpler model that fits it best in log light over codes
8..247: ``"srgb"`` or a power law g (``"linear"`` when g is within 0.05 of 1).
"""

from __future__ import annotations

import numpy as np

from viewcomp.calib.world.response import Response, parse_response

CODES = np.arange(8, 248)


def debevec_curve(frames: list[np.ndarray], exposures: list[float]) -> np.ndarray:
    """(256,) relative light per 8-bit code (the mean of the channels' curves), from
    ``frames`` (each (H, W, 3) uint8 RGB of one scene) at relative ``exposures``."""
    import cv2

    if len(frames) < 2 or any(f.dtype != np.uint8 for f in frames):
        raise ValueError("the response estimate needs >= 2 uint8 frames")
    images = [np.ascontiguousarray(f[:, :, ::-1]) for f in frames]
    times = np.asarray(exposures, np.float32)
    curve = cv2.createCalibrateDebevec().process(images, times)
    return np.asarray(curve, np.float64).reshape(256, 3).mean(axis=1)


def fit_response(curve: np.ndarray) -> tuple[Response, float]:
    """The rig.toml response that fits ``curve`` (256,) best, and its RMS misfit in natural
    log light (the curve's unknown scale is fitted too)."""
    y = np.log(np.maximum(curve[CODES], 1e-12))
    x = CODES / 255.0
    # power law: log y = c + g log x
    lx = np.log(x)
    a = np.stack([np.ones_like(lx), lx], axis=1)
    (c, g), *_ = np.linalg.lstsq(a, y, rcond=None)
    gamma_rms = float(np.sqrt(np.mean((a @ np.array([c, g]) - y) ** 2)))
    srgb = np.log(np.maximum(parse_response("srgb").decode(x.astype(np.float32)), 1e-12))
    c_s = float(np.mean(y - srgb))
    srgb_rms = float(np.sqrt(np.mean((srgb + c_s - y) ** 2)))
    if srgb_rms < gamma_rms:
        return parse_response("srgb"), srgb_rms
    if abs(g - 1.0) < 0.05:
        return parse_response("linear"), gamma_rms
    return parse_response(round(float(g), 2)), gamma_rms
