"""The captures of a camera-space set, loaded on demand as linear float32.

Images held in memory (a capture set read by :mod:`viewcomp.calib.io.captureset`) come as they
are; the geometric captures (chessboard, Gray code), listed by file, are read and linearised
on first use, with their size checked against the camera's resolution.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from viewcomp.calib.errors import FitError
from viewcomp.calib.io.captureset import CaptureSet
from viewcomp.calib.io.imageio import CaptureError, max_code_fraction, read_image, to_linear

GEOMETRIC_FIX = (
    "capture it with `viewcomp capture` (or project the patterns of `viewcomp patterns` in "
    "that order)"
)


class Captures:
    """The images of one sub-folder of a capture set, loaded on demand (linear float32)."""

    def __init__(self, cs: CaptureSet, sub: str) -> None:
        self.cs = cs
        self.sub = sub
        self.response = cs.rig.camera.response_curve()
        self.memory: Mapping[str, np.ndarray] = cs.images(sub)
        self.files = {p.stem: p for p in cs.extra.get(sub, [])}
        self.saturation: dict[str, float] = {}

    def has(self, name: str) -> bool:
        return name in self.memory or name in self.files

    def rel(self, name: str) -> str:
        p = self.files.get(name)
        return f"{self.sub}/{p.name}" if p is not None else f"{self.sub}/{name}"

    def get(self, name: str) -> np.ndarray:
        """(Hc, Wc, 3) float32 linear; raises FitError when missing."""
        if name in self.memory:
            key = (self.sub, name)
            self.saturation[name] = self.cs.raw_max_fraction.get(key, 0.0)
            return np.asarray(self.memory[name], np.float32)
        if name not in self.files:
            raise FitError(
                f"{self.sub}/{name}.png",
                f"not found: camera-space capture sets need it; {GEOMETRIC_FIX}",
            )
        try:
            raw = read_image(self.files[name])
        except CaptureError as exc:
            raise FitError(self.rel(name), str(exc)) from None
        cw, ch = self.cs.rig.camera.resolution
        if raw.shape[:2] != (ch, cw):
            raise FitError(
                self.rel(name),
                f"is {raw.shape[1]}x{raw.shape[0]}, the camera's resolution is {cw}x{ch}: "
                "capture every image of the set with the same camera settings",
            )
        self.saturation[name] = max_code_fraction(raw)
        return to_linear(raw, self.response)


def channel_mean(img: np.ndarray) -> np.ndarray:
    """(H, W, 3) -> (H, W) float32 mean of the channels."""
    a = np.asarray(img, np.float32)
    return (a[..., 0] + a[..., 1] + a[..., 2]) * np.float32(1.0 / 3.0)
