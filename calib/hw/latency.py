"""The projector -> camera latency: how long after :meth:`Projector.show` returns the camera's
frames show the new pattern, measured with a sentinel (black, then white) at the start of a
capture, so that :class:`~viewcomp.calib.hw.reader.FrameReader` can keep only frames that
began after it.

A trial shows black, takes a settled black frame as the reference, shows white (swap time t),
and reads every frame as it comes: the first frame that differs from black ended its exposure
before it was received (clock time r), so the light changed before r and any frame that starts
at or after ``t + (r - t)`` sees only white. The latency is the largest ``r - t`` of the
trials plus one refresh period (a DLP's or LCD's rise).
"""

from __future__ import annotations

import numpy as np

from viewcomp.calib.hw.frames import frame_rgb
from viewcomp.calib.hw.interface import Clock, Frame, Projector
from viewcomp.calib.hw.reader import FrameReader

#: Seconds the sentinel waits for the change before giving up (the longest plausible latency).
MAX_LATENCY = 1.5
#: A frame "changed" when its mean absolute difference from black exceeds this (0..1 scale)
#: and four times the frame-to-frame noise.
MIN_CHANGE = 0.004


def _level(f: Frame) -> np.ndarray:
    return frame_rgb(f).astype(np.float32) / np.float32(f.max_code)


def measure_latency(
    projector: Projector, reader: FrameReader, clock: Clock, trials: int = 2
) -> float | None:
    """The latency in seconds (see the module doc), or None when the camera saw no change
    (the projector is not in view, or the exposure shows nothing)."""
    w, h = projector.resolution
    black = np.zeros((h, w, 3), np.uint8)
    white = np.full((h, w, 3), 255, np.uint8)
    period = 1.0 / projector.refresh_hz
    worst = 0.0
    for _ in range(trials):
        t = projector.show(black)
        ref = reader.fresh(t + MAX_LATENCY, what="the latency sentinel (black)")
        again = reader.fresh(ref.timestamp + 1e-9, what="the latency sentinel (black)")
        noise = float(np.mean(np.abs(_level(again) - _level(ref))))
        ref_level = _level(ref)
        t_white = projector.show(white)
        while True:
            f = reader.grab()
            received = clock.now()
            if f.timestamp + f.exposure <= t_white:
                continue  # over before the swap: still black
            if float(np.mean(np.abs(_level(f) - ref_level))) > max(4 * noise, MIN_CHANGE):
                worst = max(worst, received - t_white)
                break
            if received > t_white + MAX_LATENCY + 2 * max(f.exposure, 1.0 / 30):
                return None
    projector.show(black)
    return worst + period
