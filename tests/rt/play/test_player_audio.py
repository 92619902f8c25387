"""The audio thread on the wall clock, with a simulated device (no sound card needed)."""

from __future__ import annotations

import threading
import time

import av
import numpy as np
import pytest

from viewcomp.rt.media.audio import AudioPlayer, open_alsa

RATE = 48000
CHUNK = 1024


class FakeDevice:
    """A device whose clock runs at ``speed`` x real time, with a ``buffer`` s queue."""

    def __init__(self, speed: float = 1.0, buffer: float = 0.1) -> None:
        self.rate, self.channels = RATE, 2
        self.speed, self.buffer = speed, buffer
        self.written = 0  # frames
        self.start: float | None = None
        self.lateness: list[float] = []  # heard time - due time, per write (filled by test)
        self.closed = False
        self._lock = threading.Lock()

    def _played(self) -> float:
        if self.start is None:
            return 0.0
        return min(self.written, (time.monotonic() - self.start) * self.speed * RATE)

    def delay(self) -> float:
        with self._lock:
            return (self.written - self._played()) / RATE

    def write(self, samples: np.ndarray) -> None:
        while self.delay() > self.buffer:  # blocks like a full ALSA buffer
            time.sleep(0.002)
        with self._lock:
            if self.start is None or self._played() >= self.written:  # underrun: restarts
                self.start = time.monotonic() - self.written / (self.speed * RATE)
            self.written += samples.shape[0]

    def close(self) -> None:
        self.closed = True


def _frames(seconds: float) -> list[tuple[float, av.AudioFrame]]:
    out = []
    for start in range(0, int(seconds * RATE), CHUNK):
        t = np.arange(start, start + CHUNK) / RATE
        data = (0.2 * np.sin(2 * np.pi * 440 * t)).astype(np.float32)[None, :]
        f = av.AudioFrame.from_ndarray(data, format="fltp", layout="mono")
        f.sample_rate = RATE
        out.append((start / RATE, f))
    return out


@pytest.mark.parametrize(("speed", "dropped"), [(1.0, (0.0, 0.05)), (0.7, (0.25, 0.65))])
def test_audio_follows_the_wall_clock(speed: float, dropped: tuple[float, float]) -> None:
    dev = FakeDevice(speed)
    player = AudioPlayer(dev, lead=0.12, late=0.08)
    try:
        frames = _frames(2.0)
        feeder = threading.Thread(target=lambda: [player.feed(0, t, f) for t, f in frames])
        feeder.start()
        origin = time.monotonic() + 0.2
        player.set_origin(0, origin)
        end = origin + 2.5
        while time.monotonic() < end and player.stats.written + player.stats.dropped < 1.99:
            time.sleep(0.02)
        feeder.join(timeout=5)
    finally:
        player.stop()
    s = player.stats
    print(f"\ndevice at {speed:.2f}x: written {s.written:.2f} s, dropped {s.dropped:.2f} s late")
    assert dev.closed
    assert s.written + s.dropped == pytest.approx(2.0, abs=0.03)
    assert dropped[0] <= s.dropped <= dropped[1]
    if speed != 1.0:  # what is still queued is never more than `late` + a chunk behind
        assert dev.delay() <= 0.08 + 0.1 + CHUNK / RATE


def test_no_device_means_silence() -> None:
    assert open_alsa("no-such-device-xyz") is None
