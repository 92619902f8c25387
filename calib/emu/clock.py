"""The emulator's clock: emulated seconds that advance only when a device or the caller waits.

Real devices share ``time.monotonic``; the emulated ones share a :class:`VirtualClock`
(the :class:`~viewcomp.calib.hw.interface.Clock` protocol). Sleeping advances it at once,
and the devices advance it as the hardware would take time: a projector's buffer swap waits
for the next vertical blank, a camera's grab waits until its frame is read out. So a
capture run against the emulator reports how long it would take on the devices without
waiting for it.
"""

from __future__ import annotations

import math


class VirtualClock:
    """Emulated time in seconds, starting at ``start``; never goes back."""

    def __init__(self, start: float = 0.0) -> None:
        if not math.isfinite(start):
            raise ValueError(f"the clock's start must be finite seconds, got {start}")
        self._t = float(start)

    def now(self) -> float:
        """Seconds (monotonic)."""
        return self._t

    def sleep(self, seconds: float) -> None:
        """Advance by ``seconds`` (>= 0) without waiting."""
        s = float(seconds)
        if not (math.isfinite(s) and s >= 0):
            raise ValueError(f"sleep takes seconds >= 0, got {seconds}")
        self._t += s

    def advance_to(self, t: float) -> None:
        """Advance to time ``t`` (seconds); a time already past leaves the clock as it is
        (a device that is ready does not wait)."""
        if t > self._t:
            self._t = float(t)
