"""Camera frames into captures: the mean of several :class:`~viewcomp.calib.hw.interface.Frame`
as one RGB image on the 8- or 16-bit scale the checks and the capture set read.

A capture is (H, W, 3) uint8 (one 8-bit frame, as the camera gave it) or uint16 (anything
else: the mean of several frames, or frames of more than 8 bits, scaled so that the frame's
full scale, :attr:`Frame.max_code`, becomes 65535: the same 0..1 scale at more precision). A
mono frame (H, W) becomes three equal channels (:mod:`viewcomp.calib.hw.mono` says what such a
capture can calibrate).
"""

from __future__ import annotations

import numpy as np

from viewcomp.calib.hw.interface import DeviceError, Frame


def frame_rgb(frame: Frame) -> np.ndarray:
    """The frame's image as (H, W, 3), mono repeated into three equal channels."""
    img = frame.image
    if img.ndim == 2:
        return np.repeat(img[:, :, None], 3, axis=2)
    if img.ndim == 3 and img.shape[2] == 1:
        return np.repeat(img, 3, axis=2)
    if img.ndim == 3 and img.shape[2] == 3:
        return img
    raise DeviceError(f"a camera frame must be (H, W) or (H, W, 3), got {img.shape}")


def average_frames(frames: list[Frame]) -> np.ndarray:
    """The mean of ``frames`` (one size, dtype and bit depth) as an (H, W, 3) capture: one
    8-bit frame is returned as is (uint8); otherwise uint16 codes
    ``round(mean * 65535 / max_code)`` (8-bit frames: ``round(257 * mean)``)."""
    if not frames:
        raise ValueError("average_frames needs at least one frame")
    first = frames[0]
    for f in frames[1:]:
        if f.image.shape != first.image.shape or f.image.dtype != first.image.dtype:
            raise DeviceError(
                f"the camera changed its frame size or format between frames ({first.image.shape} "
                f"{first.image.dtype}, then {f.image.shape} {f.image.dtype}): fix the camera's "
                "mode (resolution, pixel format) and capture again"
            )
        if f.bits != first.bits:
            raise DeviceError(
                f"the camera changed its bit depth between frames ({first.bits}, then {f.bits})"
            )
    if first.image.dtype not in (np.uint8, np.uint16):
        raise DeviceError(f"camera frames must be uint8 or uint16, got {first.image.dtype}")
    if len(frames) == 1 and first.image.dtype == np.uint8 and first.bits == 8:
        return frame_rgb(first).copy()
    total = np.zeros(frame_rgb(first).shape, np.float64)
    for f in frames:
        total += frame_rgb(f)
    scale = 65535.0 / (first.max_code * len(frames))
    return np.rint(np.minimum(total * scale, 65535.0)).astype(np.uint16)
