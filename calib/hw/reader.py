"""Reading frames that show what the projector shows: presentation sync, retries, averaging.

A camera's driver queues frames, and a frame's exposure may have started before the pattern
it is filed under reached the screen. :class:`FrameReader` keeps only frames whose exposure
started at or after a given clock time (``not_before``: the projector's swap time plus the
measured latency, :mod:`viewcomp.calib.hw.latency`) and, when asked, that were taken at the
expected exposure and gain (a frame exposed before a control change took effect is dropped):
it drains the driver's queue by timestamps, not by a fixed count of dropped frames.

A :class:`~viewcomp.calib.hw.interface.FrameError` (one failed read) is retried up to
``retries`` times in a row; a :class:`~viewcomp.calib.hw.interface.DeviceError` (the device is
gone) fails at once, naming the camera.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from viewcomp.calib.hw.frames import average_frames
from viewcomp.calib.hw.interface import Camera, Clock, DeviceError, Frame, FrameError

Log = Callable[[str], None]

#: Seconds a fresh frame may take beyond ``not_before`` plus a few frames' exposure.
FRESH_TIMEOUT = 5.0
#: Stale frames read, on a clock that has not moved, before giving up (a simulated clock that
#: does not move while a driver returns queued frames at once would never reach the deadline).
MAX_STALE = 2000


class FrameReader:
    """Fresh frames from ``camera`` on ``clock`` (see the module doc)."""

    def __init__(self, camera: Camera, clock: Clock, log: Log, retries: int = 3) -> None:
        if retries < 0:
            raise ValueError(f"retries must be >= 0, got {retries}")
        self.camera = camera
        self.clock = clock
        self.log = log
        self.retries = retries
        #: frames read and thrown away as stale (started too early or at old settings)
        self.dropped = 0
        #: failed reads retried
        self.failed = 0
        #: the latest frame read (None before the first)
        self.last: Frame | None = None

    def grab(self) -> Frame:
        """One frame, retrying failed reads (``retries`` in a row at most)."""
        errors = 0
        while True:
            try:
                self.last = self.camera.grab()
                return self.last
            except FrameError as e:
                errors += 1
                self.failed += 1
                if errors > self.retries:
                    raise DeviceError(
                        f"{self.camera.name}: {errors} reads in a row failed (last: {e}): check "
                        "the cable and the USB bandwidth (one camera per USB controller, a "
                        "shorter cable, a lower resolution with --camera-size), and capture again"
                    ) from e
                self.log(f"warning: {self.camera.name}: a read failed ({e}); trying again")
            except DeviceError as e:
                if self.camera.name in str(e):
                    raise
                raise DeviceError(f"{self.camera.name}: {e}") from e

    def fresh(
        self,
        not_before: float,
        exposure: float | None = None,
        gain: float | None = None,
        what: str = "a capture",
    ) -> Frame:
        """The next frame whose exposure started at or after ``not_before`` (clock seconds)
        and, when given, was taken at ``exposure`` (s) and ``gain`` (x) as the camera reads
        them back. Raises DeviceError (naming ``what``) when none comes in time."""
        waited = 0
        longest = max(exposure or 0.0, 1.0 / 30.0)
        called = self.clock.now()
        deadline = max(called, not_before) + FRESH_TIMEOUT + 8 * longest
        while True:
            f = self.grab()
            if f.timestamp >= not_before and _same(f.exposure, exposure) and _same(f.gain, gain):
                return f
            self.dropped += 1
            waited += 1
            now = self.clock.now()
            if now > deadline or (waited >= MAX_STALE and now == called):
                want = f"started at or after {not_before:.3f} s"
                if exposure is not None:
                    want += f" at exposure {exposure:.6g} s"
                raise DeviceError(
                    f"{what}: {self.camera.name} delivered {waited} frames, none {want} (the "
                    f"last started at {f.timestamp:.3f} s, exposure {f.exposure:.6g} s, gain "
                    f"{f.gain:.4g}; clock now {self.clock.now():.3f} s): its timestamps or "
                    "its exposure read-back are wrong, or it stopped delivering new frames; "
                    "check the camera's backend, or raise --settle"
                )

    def frames(
        self,
        n: int,
        not_before: float,
        exposure: float | None = None,
        gain: float | None = None,
        what: str = "a capture",
    ) -> list[Frame]:
        """``n`` fresh frames (:meth:`fresh`), each later than the one before."""
        if n < 1:
            raise ValueError(f"n must be >= 1, got {n}")
        out: list[Frame] = []
        for _ in range(n):
            f = self.fresh(not_before, exposure, gain, what)
            out.append(f)
            not_before = float(np.nextafter(f.timestamp, np.inf))
        return out

    def average(
        self,
        n: int,
        not_before: float,
        exposure: float | None = None,
        gain: float | None = None,
        what: str = "a capture",
    ) -> np.ndarray:
        """The mean of ``n`` fresh frames as an (H, W, 3) capture
        (:func:`~viewcomp.calib.hw.frames.average_frames`)."""
        return average_frames(self.frames(n, not_before, exposure, gain, what))


def _same(got: float, want: float | None) -> bool:
    """``got`` equals ``want`` (None: anything) to 0.1 %."""
    return want is None or abs(got - want) <= 1e-3 * max(abs(want), 1e-12)
