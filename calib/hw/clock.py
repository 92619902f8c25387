"""The clocks of :class:`~viewcomp.calib.hw.interface.Clock`: real time for real devices, and a
simulated clock that only moves when someone waits on it (the simulated rig's devices advance
it as real ones would take time, so a test knows how long a capture takes without waiting)."""

from __future__ import annotations

import time


class MonotonicClock:
    """Real time: ``time.monotonic`` (seconds; on Linux the clock V4L2 stamps its buffers with)
    and ``time.sleep``."""

    def now(self) -> float:
        """Seconds since an arbitrary start (monotonic)."""
        return time.monotonic()

    def sleep(self, seconds: float) -> None:
        """Wait ``seconds`` (negative: not at all)."""
        if seconds > 0:
            time.sleep(seconds)


class SimClock:
    """Simulated time: starts at ``start`` seconds and advances only through :meth:`sleep` and
    :meth:`advance_to` (never backwards)."""

    def __init__(self, start: float = 0.0) -> None:
        self._t = float(start)

    def now(self) -> float:
        """The simulated time (s)."""
        return self._t

    def sleep(self, seconds: float) -> None:
        """Advance by ``seconds`` (negative: not at all)."""
        if seconds > 0:
            self._t += float(seconds)

    def advance_to(self, t: float) -> None:
        """Advance to time ``t`` when it is later than now."""
        self._t = max(self._t, float(t))
