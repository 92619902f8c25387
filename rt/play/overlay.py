"""The player's overlay: angle, eye, fps and drops drawn with OpenCV into a texture."""

from __future__ import annotations

from typing import Any

import numpy as np


class Overlay:
    """Angle, eye, fps and drops drawn with OpenCV into a texture, blitted top-left."""

    SIZE = (420, 74)

    def __init__(self, ctx: Any) -> None:
        w, h = self.SIZE
        self.tex = ctx.texture((w, h), 3, dtype="f1")
        self.fbo = ctx.framebuffer(color_attachments=[self.tex])
        self.text: tuple[str, ...] = ()
        self.updated = -1.0

    def update(self, lines: tuple[str, ...]) -> None:
        import cv2

        if lines == self.text:
            return
        w, h = self.SIZE
        img = np.zeros((h, w, 3), np.uint8)
        for i, line in enumerate(lines):
            cv2.putText(
                img,
                line,
                (8, 20 + 22 * i),
                cv2.FONT_HERSHEY_SIMPLEX,
                0.5,
                (255, 255, 255),
                1,
                cv2.LINE_AA,
            )
        self.tex.write(np.ascontiguousarray(img[::-1]))  # GL rows go bottom-up
        self.text = lines

    def release(self) -> None:
        self.fbo.release()
        self.tex.release()
