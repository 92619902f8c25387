"""An OpenCV ``VideoCapture`` device as a :class:`~viewcomp.calib.hw.interface.Camera`.

Controls in the units of :data:`~viewcomp.calib.hw.interface.CONTROLS`, converted from the
driver's, which depend on OpenCV's backend (``VideoCapture.getBackendName()``):

- ``exposure``: ``CAP_PROP_EXPOSURE`` is V4L2's ``exposure_time_absolute`` in units of 100 us
  (Linux), log2 of seconds on DirectShow and Media Foundation (Windows: -13 .. 0). Another
  backend (GStreamer, AVFoundation, a fake) is guessed from the sign of the value it reports
  (> 0: 100 us units, <= 0: log2 s) and said so in :attr:`OpenCVCamera.name`.
- ``auto_exposure``: V4L2 takes 1 (manual) / 3 (aperture priority); the others 0.25 / 0.75.
- ``auto_white_balance``, ``white_balance`` (kelvin), ``autofocus``, ``focus``: as the
  driver has them.
- ``gain`` is absent: ``CAP_PROP_GAIN`` is in driver units of unknown scale, not a linear
  factor; lock it in the camera's own tool.

Timestamps: V4L2 stamps each buffer on ``CLOCK_MONOTONIC`` (``CAP_PROP_POS_MSEC``), the clock
of :class:`~viewcomp.calib.hw.clock.MonotonicClock`: the frame's start is that stamp minus the
exposure. Where the backend's stamp is not on that clock, the start is bounded from below by
the reads: the driver queues at most ``queue`` frames (``CAP_PROP_BUFFERSIZE``), so the frame a
read returns finished after the read ``queue`` reads earlier began, and its exposure began at
most one exposure and one frame period before that. Frames are therefore never taken as newer
than they are (at the price of ``queue`` extra frames per capture).
"""

from __future__ import annotations

import math
import sys
from collections import deque

import numpy as np

from viewcomp.calib.hw.clock import MonotonicClock
from viewcomp.calib.hw.interface import Clock, ControlRange, DeviceError, Frame, FrameError

V4L2_UNIT = 1e-4  # seconds per CAP_PROP_EXPOSURE unit on V4L2
LOG2_BACKENDS = ("DSHOW", "MSMF")


def relative_exposure(base: float, value: float) -> float:
    """A driver exposure ``value`` relative to ``base``, both in the driver's units: linear
    (V4L2's 100 us steps) when ``base`` > 0; log2 of seconds (DirectShow, MSMF: -13 .. 0) when
    ``base`` <= 0."""
    return value / base if base > 0 else 2.0 ** (value - base)


def exposure_value(base: float, relative: float) -> float:
    """The driver value that is ``relative`` times ``base`` (the inverse of
    :func:`relative_exposure`)."""
    return base * relative if base > 0 else base + math.log2(relative)


class OpenCVCamera:
    """OpenCV ``VideoCapture`` device ``index``, optionally at ``size`` (width, height); see the
    module doc for the controls and timestamps. ``clock`` must be the procedure's."""

    def __init__(
        self, index: int, size: tuple[int, int] | None = None, clock: Clock | None = None
    ) -> None:
        import cv2

        self._cv2 = cv2
        self.index = index
        self._clock = clock if clock is not None else MonotonicClock()
        self._cap = cv2.VideoCapture(index)
        if not self._cap.isOpened():
            raise DeviceError(
                f"cannot open camera {index}: check that it is connected and not used by "
                "another program, and choose it with --camera N (0 is the first)"
            )
        try:
            self.backend = str(self._cap.getBackendName())
        except Exception:  # an old OpenCV, or a stand-in without the call
            self.backend = "unknown"
        if size is not None:
            self._cap.set(cv2.CAP_PROP_FRAME_WIDTH, size[0])
            self._cap.set(cv2.CAP_PROP_FRAME_HEIGHT, size[1])
        self._cap.set(cv2.CAP_PROP_BUFFERSIZE, 1)
        self.queue = max(1, int(self._cap.get(cv2.CAP_PROP_BUFFERSIZE) or 4))
        fps = float(self._cap.get(cv2.CAP_PROP_FPS) or 0.0)
        self.period = 1.0 / fps if 1.0 <= fps <= 1000.0 else 1.0 / 5.0
        raw = float(self._cap.get(cv2.CAP_PROP_EXPOSURE))
        if self.backend == "V4L2":
            self.log2_units = False
            self.units = "CAP_PROP_EXPOSURE in 100 us units (V4L2)"
        elif self.backend in LOG2_BACKENDS:
            self.log2_units = True
            self.units = f"CAP_PROP_EXPOSURE in log2 seconds ({self.backend})"
        else:
            self.log2_units = raw <= 0
            self.units = (
                "CAP_PROP_EXPOSURE guessed as "
                + ("log2 seconds" if self.log2_units else "100 us units")
                + f" (OpenCV backend {self.backend}, from the sign of {raw:g})"
            )
        self._name = f"camera {index} (OpenCV {self.backend})"
        # (clock time from which it applies, exposure s), newest last
        self._exposures: deque[tuple[float, float]] = deque(maxlen=8)
        self._exposures.append((-math.inf, self._to_seconds(raw)))
        self._starts: deque[float] = deque(maxlen=self.queue + 1)  # call times of recent reads
        self._seq = 0
        frame = self.grab()
        self._size = (int(frame.image.shape[1]), int(frame.image.shape[0]))
        self._channels = 1 if frame.image.ndim == 2 else 3
        if size is not None and self._size != tuple(size):
            print(
                f"{self._name}: asked for {size[0]}x{size[1]}, the driver delivers "
                f"{self._size[0]}x{self._size[1]}",
                file=sys.stderr,
            )

    @property
    def name(self) -> str:
        """``camera N (OpenCV BACKEND)``; :attr:`units` says how the exposure is converted."""
        return self._name

    @property
    def resolution(self) -> tuple[int, int]:
        """(width, height) of the frames the driver delivers."""
        return self._size

    @property
    def channels(self) -> int:
        """1 when the driver delivers single-channel frames, else 3."""
        return self._channels

    def _to_seconds(self, raw: float) -> float:
        return 2.0**raw if self.log2_units else raw * V4L2_UNIT

    def _to_driver(self, seconds: float) -> float:
        return math.log2(seconds) if self.log2_units else seconds / V4L2_UNIT

    def _props(self) -> dict[str, int]:
        cv2 = self._cv2
        return {
            "exposure": cv2.CAP_PROP_EXPOSURE,
            "white_balance": cv2.CAP_PROP_WB_TEMPERATURE,
            "focus": cv2.CAP_PROP_FOCUS,
            "auto_exposure": cv2.CAP_PROP_AUTO_EXPOSURE,
            "auto_white_balance": cv2.CAP_PROP_AUTO_WB,
            "autofocus": cv2.CAP_PROP_AUTOFOCUS,
        }

    def controls(self) -> dict[str, ControlRange]:
        """The controls OpenCV maps (it cannot say which the device lacks: :meth:`set` then
        raises). Ranges are the drivers' usual ones, not queried."""
        exp = ControlRange(2.0**-13, 1.0) if self.log2_units else ControlRange(V4L2_UNIT, 10.0)
        return {
            "exposure": exp,
            "white_balance": ControlRange(2000.0, 10000.0),
            "focus": ControlRange(0.0, 1023.0),
            "auto_exposure": ControlRange(0.0, 1.0, 1.0),
            "auto_white_balance": ControlRange(0.0, 1.0, 1.0),
            "autofocus": ControlRange(0.0, 1.0, 1.0),
        }

    def _prop(self, control: str) -> int:
        props = self._props()
        if control not in props:
            raise DeviceError(f"{self._name} has no control {control!r} (OpenCV maps none)")
        return props[control]

    def get(self, control: str) -> float:
        """The control as the driver reports it, in the units of CONTROLS."""
        raw = float(self._cap.get(self._prop(control)))
        if control == "exposure":
            return self._to_seconds(raw)
        if control == "auto_exposure":
            return 0.0 if raw in (1.0, 0.25) else 1.0
        return raw

    def set(self, control: str, value: float) -> float:
        """Set ``control`` and return what the driver then reports; DeviceError when the
        driver refuses (or reports something else for an automatic mode)."""
        prop = self._prop(control)
        if control == "auto_exposure":
            # V4L2 takes 1 (manual) / 3 (auto); other backends the legacy 0.25 / 0.75
            for raw in (1.0, 0.25) if value == 0 else (3.0, 0.75):
                if self._cap.set(prop, raw) and float(self._cap.get(prop)) == raw:
                    return self.get(control)
            raise DeviceError(f"{self._name}: the driver refuses auto_exposure = {value:g}")
        raw = self._to_driver(value) if control == "exposure" else float(value)
        if not self._cap.set(prop, raw):
            raise DeviceError(f"{self._name}: the driver refuses {control} = {value:g}")
        got = self.get(control)
        if control == "exposure":
            self._exposures.append((self._clock.now(), got))
        return got

    def _exposure_at(self, t: float) -> float:
        for since, seconds in reversed(self._exposures):
            if since <= t:
                return seconds
        return self._exposures[0][1]

    def grab(self) -> Frame:
        """One frame (RGB, or mono as the driver gives it) with its start time (module doc).
        A failed read is a FrameError (retried by the procedure)."""
        call = self._clock.now()
        ok, image = self._cap.read()
        back = self._clock.now()
        self._starts.append(call)
        if not ok or image is None:
            raise FrameError(
                f"{self._name} delivered no frame: check the connection and that no other "
                "program uses it"
            )
        exposure = self._exposures[-1][1]
        start = self._driver_start(back, exposure)
        if start is None:
            # finished after the read `queue` reads ago began (how long a read blocked is no
            # proof: decoding a queued frame can take as long as waiting for a new one)
            done_after = self._starts[0] if len(self._starts) > self.queue else -math.inf
            start = done_after - exposure - self.period
        self._seq += 1
        if image.ndim == 3 and image.shape[2] == 3:
            image = np.ascontiguousarray(image[:, :, ::-1])  # BGR -> RGB
        elif image.ndim == 3 and image.shape[2] == 1:
            image = image[:, :, 0]
        bits = 8 if image.dtype == np.uint8 else 16
        return Frame(
            image=image,
            timestamp=start,
            exposure=self._exposure_at(start),
            gain=1.0,
            sequence=self._seq,
            bits=bits,
        )

    def _driver_start(self, back: float, exposure: float) -> float | None:
        """The exposure's start from V4L2's buffer stamp, when it is on our clock."""
        if self.backend != "V4L2" or not isinstance(self._clock, MonotonicClock):
            return None
        stamp = float(self._cap.get(self._cv2.CAP_PROP_POS_MSEC)) / 1000.0
        if not (back - 10.0 < stamp <= back + 1e-3):
            return None
        return stamp - exposure

    def close(self) -> None:
        """Release the device."""
        self._cap.release()

    def __enter__(self) -> OpenCVCamera:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
