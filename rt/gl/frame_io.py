"""Frames in and out of the GL compensator: RGB or yuv420p uploads, a pixel buffer already on
the GPU, and the read-back of the result."""

from __future__ import annotations

from typing import Any

import moderngl
import numpy as np

from viewcomp.rt.gl.context import finish
from viewcomp.rt.media.frames import Planes, yuv_coefficients


class FrameIO:
    """Uploads and read-back of :class:`~viewcomp.rt.gl.compensator.Compensator` (a mixin)."""

    ctx: moderngl.Context
    width: int
    height: int
    fbo: Any
    _rgb: Any
    _y: Any
    _uv: Any
    _uv_host: np.ndarray
    _yuv_key: tuple[str, str]
    _input: int

    def upload(self, frame: np.ndarray) -> None:
        """Upload an RGB frame (H, W, 3) uint8 (levels 0..255) as the next input."""
        if frame.shape != (self.height, self.width, 3) or frame.dtype != np.uint8:
            raise ValueError(
                f"frame must be uint8 {(self.height, self.width, 3)}, got {frame.dtype} "
                f"{frame.shape} (scale with viewcomp.rt.media.frames.fit_rgb first)"
            )
        self._rgb.write(np.ascontiguousarray(frame))
        self._input = 0

    def upload_planes(self, planes: Planes) -> None:
        """Upload a yuv420p frame (converted to RGB levels in the shader, see yuv.glsl)."""
        planes.check()
        if planes.shape != (self.height, self.width):
            raise ValueError(
                f"planes must be {(self.height, self.width)}, got {planes.shape} "
                "(the video reader fits frames to the grid)"
            )
        yuv_coefficients(planes.colorspace, planes.color_range)  # validates both
        self._y.write(np.ascontiguousarray(planes.y))
        self._uv_host[..., 0] = planes.u  # interleave: one chroma texture, half the reads
        self._uv_host[..., 1] = planes.v
        self._uv.write(self._uv_host)
        self._yuv_key = (planes.colorspace, planes.color_range)
        self._input = 1

    def upload_buffer(self, buffer: moderngl.Buffer) -> None:
        """Upload an RGB frame already on the GPU: a pixel buffer of this context holding
        (H, W, 3) uint8 levels in :meth:`upload`'s order (a copy within the driver)."""
        if buffer.size < self.width * self.height * 3:
            raise ValueError(
                f"the buffer holds {buffer.size} bytes, a frame needs "
                f"{self.width * self.height * 3}"
            )
        self._rgb.write(buffer, alignment=1)
        self._input = 0

    def read(self, out: np.ndarray | None = None) -> np.ndarray:
        """Read back the last draw as (H, W, 3) uint8 (into ``out`` if given, no copy).

        Waits for the draw with the GIL released (:func:`viewcomp.rt.gl.context.finish`), so
        other Python threads (decoder, encoder) run meanwhile.
        """
        shape = (self.height, self.width, 3)
        if out is None:
            out = np.empty(shape, np.uint8)
        elif out.shape != shape or out.dtype != np.uint8 or not out.flags.c_contiguous:
            raise ValueError(f"out must be a C-contiguous uint8 array {shape}, got {out.shape}")
        finish(self.ctx)
        self.fbo.read_into(out, components=3, alignment=1)
        return out
