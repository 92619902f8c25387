"""Progress of a capture with the time left, estimated from the clock the devices share."""

from __future__ import annotations

from collections.abc import Callable

from viewcomp.calib.hw.interface import Clock


def duration(seconds: float) -> str:
    """``12 s``, ``3 min 05 s``, ``1 h 02 min``."""
    s = max(0, round(seconds))
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {(s % 3600) // 60:02d} min"


class Progress:
    """Logs ``what (k/total, T left)`` after each of ``total`` steps; the time left is the mean
    time per step so far (on ``clock``, from :meth:`start`) times the steps left."""

    def __init__(self, total: int, clock: Clock, log: Callable[[str], None]) -> None:
        self.total = total
        self.clock = clock
        self.log = log
        self.done = 0
        self.t0 = clock.now()

    def start(self) -> None:
        """Start timing now (after the set-up: latency, exposure search)."""
        self.t0 = self.clock.now()
        self.done = 0

    def left(self) -> float:
        """Seconds left, estimated."""
        if self.done == 0:
            return float("nan")
        return (self.clock.now() - self.t0) / self.done * (self.total - self.done)

    def step(self, what: str) -> None:
        """One step done: log it with the time left."""
        self.done += 1
        left = self.left()
        tail = "" if left != left else f", {duration(left)} left"
        self.log(f"{what} ({self.done}/{self.total}{tail})")
