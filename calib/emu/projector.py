"""The emulated projector (the :class:`~viewcomp.calib.hw.interface.Projector` protocol).

:meth:`EmulatedProjector.show` waits for the next vertical blank (a vsync'd buffer swap:
the clock advances to it) and returns that time. The light on the screen changes
``latency`` refreshes later (2..4, drawn once per projector from its seed and not told to the
caller: the projector's own processing), one refresh later still for a late frame (a fault,
:class:`~viewcomp.calib.emu.faults.Faults`). What is on screen at any time, and so what a
camera exposure integrates, comes from :meth:`segments`: the timeline of shown patterns.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from viewcomp.calib.emu.clock import VirtualClock
from viewcomp.calib.emu.dlp import DlpModel
from viewcomp.calib.emu.faults import Faults


@dataclass(frozen=True)
class Shown:
    """One pattern on the timeline: ``image`` (H, W, 3) uint8 (read-only) lights the screen
    from ``t_light`` (s); ``index`` counts show() calls from 0 (-1: the black before any);
    ``t_swap`` the swap time show() returned."""

    index: int
    t_swap: float
    t_light: float
    image: np.ndarray


class EmulatedProjector:
    """A DLP projector of ``resolution`` (W, H) on ``clock``, with ``model`` for its light.

    ``latency``: refreshes between the swap and the light (None: drawn from ``rng`` in 2..4).
    """

    def __init__(
        self,
        clock: VirtualClock,
        resolution: tuple[int, int],
        model: DlpModel,
        rng: np.random.Generator,
        faults: Faults | None = None,
        latency: int | None = None,
    ) -> None:
        w, h = resolution
        if w < 1 or h < 1:
            raise ValueError(f"a projector resolution is two sizes >= 1, got {resolution}")
        self.clock = clock
        self.model = model
        self._resolution = (int(w), int(h))
        self._rng = rng
        self.faults = faults or Faults()
        self.latency = int(rng.integers(2, 5)) if latency is None else int(latency)
        if not 0 <= self.latency <= 16:
            raise ValueError(f"latency is 0..16 refreshes, got {latency}")
        black = np.zeros((h, w, 3), np.uint8)
        black.setflags(write=False)
        self.timeline: list[Shown] = [Shown(-1, -math.inf, -math.inf, black)]
        #: show() indices whose light came one refresh late.
        self.late: list[int] = []
        self._shows = 0
        self._swaps: list[float] = []  # every show()'s swap time, by index

    @property
    def resolution(self) -> tuple[int, int]:
        """(width, height) in pixels."""
        return self._resolution

    @property
    def refresh_hz(self) -> float:
        """The refresh rate (Hz)."""
        return self.model.refresh_hz

    @property
    def shows(self) -> int:
        """How many times show() was called."""
        return self._shows

    def swap_time(self, index: int) -> float | None:
        """The swap time of show() call ``index`` (0-based), None if not shown yet."""
        return self._swaps[index] if 0 <= index < len(self._swaps) else None

    def show(self, image: np.ndarray) -> float:
        """Show (H, W, 3) uint8 RGB from the next vertical blank on; returns the swap time."""
        w, h = self._resolution
        img = np.asarray(image)
        if img.shape != (h, w, 3) or img.dtype != np.uint8:
            raise ValueError(
                f"the projector shows (H, W, 3) uint8 = {(h, w, 3)}, got {img.shape} {img.dtype}"
            )
        p = self.model.period
        now = self.clock.now()
        t_swap = (math.floor(now / p + 1e-9) + 1) * p
        self.clock.advance_to(t_swap)
        index = self._shows
        self._shows += 1
        self._swaps.append(t_swap)
        delay = self.latency
        if self.faults.is_late(index, self._rng):
            delay += 1
            self.late.append(index)
        frozen = img.copy()
        frozen.setflags(write=False)
        t_light = t_swap + delay * p
        # a later swap never lights before an earlier one (the display pipeline is in order)
        t_light = max(t_light, self.timeline[-1].t_light)
        self.timeline.append(Shown(index, t_swap, t_light, frozen))
        return t_swap

    def segments(self, t0: float, t1: float) -> list[tuple[float, float, Shown]]:
        """The patterns on screen during [t0, t1]: (from, to, shown), in time order, clipped
        to the window; empty for an empty window."""
        out = []
        tl = self.timeline
        for k, s in enumerate(tl):
            end = tl[k + 1].t_light if k + 1 < len(tl) else math.inf
            a, b = max(s.t_light, t0), min(end, t1)
            if b > a:
                out.append((a, b, s))
        return out

    def forget_before(self, t: float) -> None:
        """Drop the patterns that stopped lighting the screen before time ``t`` (no exposure
        that starts at ``t`` or later can see them)."""
        tl = self.timeline
        k = 0
        while k + 1 < len(tl) and tl[k + 1].t_light <= t:
            k += 1
        del tl[:k]

    def shown_at(self, t: float) -> Shown:
        """The pattern lighting the screen at time ``t`` (its image is (H, W, 3) uint8,
        read-only)."""
        current = self.timeline[0]
        for s in self.timeline:
            if s.t_light <= t:
                current = s
        return current

    def close(self) -> None:
        """Nothing to release."""
        return None
