"""A camera device is read by a thread that keeps only the newest frame (rt/track/source.py)."""

from __future__ import annotations

import itertools
import threading
import time

import numpy as np

from viewcomp.rt.track.source import FrameSource, NewestFrame


class FakeCamera:
    """Frames 0, 1, 2, ... (the index in every pixel) every ``period`` seconds, ``n`` of
    them, then the end; a driver queue of any depth is what NewestFrame must not see."""

    def __init__(self, n: int, period: float = 0.01) -> None:
        self.n, self.period, self.i = n, period, 0
        self.released = threading.Event()

    def read(self) -> tuple[bool, np.ndarray | None]:
        if self.i >= self.n or self.released.is_set():
            return False, None
        time.sleep(self.period)
        self.i += 1
        return True, np.full((4, 6, 3), self.i - 1, np.uint8)

    def release(self) -> None:
        self.released.set()


def test_a_slow_reader_gets_the_newest_frame_and_the_rest_are_counted_as_dropped():
    reader = NewestFrame(FakeCamera(40, period=0.005))
    taken = []
    while (item := reader.take()) is not None:
        taken.append(int(item[0][0, 0, 0]))
        time.sleep(0.03)  # a tracker six frame periods slow
    assert taken == sorted(taken) and taken[-1] == 39  # in order, and the last one delivered
    assert len(taken) < 20 and reader.dropped == 40 - len(taken)
    gaps = np.diff(taken)
    assert np.median(gaps) >= 3  # frames in between were skipped, not queued


def test_a_live_frame_source_reads_on_its_thread_and_close_stops_it():
    cam = FakeCamera(10_000, period=0.002)
    src = FrameSource.__new__(FrameSource)  # a device source over the fake camera
    src.src, src.fps, src.realtime, src.live = "0", 30.0, False, True
    src._cap, src._files, src._first, src._reader = cam, [], None, None  # type: ignore[assignment]
    src.size = (6, 4)
    frames = []
    for frame in src:
        frames.append(frame)
        if len(frames) == 5:
            break
    assert [f.index for f in frames] == list(range(5))
    assert all(f.image.shape == (4, 6, 3) for f in frames)
    assert all(b.captured >= a.captured for a, b in itertools.pairwise(frames))
    src.close()
    assert cam.released.is_set() and src._reader is not None
    assert not src._reader._thread.is_alive()
