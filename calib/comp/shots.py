"""Shots in video: cut detection and the adaptive tone map's smoothing within a shot.

A *cut* is a frame whose thumbnail differs from the last one's by more than
``CUT_THRESHOLD`` (the mean absolute difference of a 4 x 4 grid of mean encoded levels, as a
fraction of full scale): a new shot. At a cut the field jumps to the new shot's (chosen by a
whole search), so it is settled from the cut's first frame on; within a shot each frame's
field (a local search from the last) is eased in exponentially with time constant ``tau``
seconds, so the picture's brightness never steps.

Cuts are detected on every frame by one :class:`ShotDetector`: inside
:class:`~viewcomp.calib.comp.compensation.Compensation` when it sees every frame (``render``),
and on the frame thread of the embedding API (``play``, ``LiveRenderer``), whose tone worker
sees only some frames and is told of a cut with the request (``Compensation(..., cut=)``), so
that the same rule decides in every path and a cut does not wait for the worker's rest.
"""

from __future__ import annotations

import numpy as np

from viewcomp.calib.model.gamut import ToneField

#: A thumbnail whose 4 x 4 block means move by more than this (fraction of full scale) on
#: average starts a new shot.
CUT_THRESHOLD = 0.08
_BLOCKS = 4


def block_means(thumb: np.ndarray) -> np.ndarray:
    """The mean encoded level (0..1) of each of a 4 x 4 grid of blocks of an (h, w, 3) uint8
    thumbnail, per channel: (4, 4, 3)."""
    h, w = thumb.shape[:2]
    ys = np.linspace(0, h, _BLOCKS + 1).astype(int)
    xs = np.linspace(0, w, _BLOCKS + 1).astype(int)
    out = np.zeros((_BLOCKS, _BLOCKS, 3))
    for i in range(_BLOCKS):
        for j in range(_BLOCKS):
            block = thumb[ys[i] : max(ys[i + 1], ys[i] + 1), xs[j] : max(xs[j + 1], xs[j] + 1)]
            out[i, j] = block.reshape(-1, 3).mean(axis=0) / 255.0
    return out


class ShotDetector:
    """Cut detection over consecutive thumbnails (module docstring); feed it every frame."""

    def __init__(self) -> None:
        self._blocks: np.ndarray | None = None

    def is_cut(self, thumb: np.ndarray) -> bool:
        """Whether ``thumb`` starts a new shot (the first frame does); remembers it."""
        blocks = block_means(thumb)
        last, self._blocks = self._blocks, blocks
        if last is None or last.shape != blocks.shape:
            return True
        return float(np.mean(np.abs(blocks - last))) > CUT_THRESHOLD


class FieldSmoother:
    """Cut detection and exponential smoothing of the adaptive field over a video's frames.

    Args:
        tau: the time constant (s) within a shot; 0: no smoothing.
    """

    def __init__(self, tau: float = 0.0) -> None:
        self.tau = float(tau)
        self.state: ToneField | None = None
        self.raw: ToneField | None = None  # the last frame's field before smoothing
        self.t: float | None = None
        self.shots = ShotDetector()

    def is_cut(self, thumb: np.ndarray) -> bool:
        """Whether ``thumb`` starts a new shot (:meth:`ShotDetector.is_cut`)."""
        return self.shots.is_cut(thumb)

    def update(self, t: float, field: ToneField, cut: bool) -> ToneField:
        """Feed the field chosen for the frame at time ``t`` (s); returns the one to show."""
        self.raw = field
        state = self.state
        if cut or state is None or self.t is None or self.tau <= 0 or state.nodes != field.nodes:
            self.state = field
        else:
            k = 1.0 - float(np.exp(-max(t - self.t, 0.0) / self.tau))
            self.state = state.blend(field, k)
        self.t = t
        return self.state
