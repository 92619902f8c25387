"""The device interfaces of `viewcomp capture`: a camera, a projector and the clock they share.

Every backend - OpenCV/V4L2 webcams, gphoto2 DSLRs, GenICam machine-vision cameras, a vendor
SDK loaded with ``--camera-backend module:factory``, and the hardware emulator
(:mod:`viewcomp.calib.emu`) - implements these protocols, and the capture procedure
(:mod:`viewcomp.calib.hw.procedure`) talks to nothing else: the code a user's capture runs is
the code the tests run against the emulator.

Conventions:

- Times are seconds on one :class:`Clock` (``time.monotonic`` for real devices; the emulator's
  own clock, which advances as the devices would, so a test knows how long the real capture
  takes without waiting for it).
- Camera controls have fixed names and units (:data:`CONTROLS`): exposure in seconds, gain as
  a linear factor (1 = the sensor's base), white balance in kelvin, focus in the driver's
  units, the three automatic modes as 0 (off) / 1 (on). A backend converts from its driver's
  units; a control the device lacks is absent from :meth:`Camera.controls`.
- Images are numpy arrays, row 0 at the top. The projector takes (H, W, 3) uint8 RGB at its
  resolution. A camera frame is (Hc, Wc, 3) RGB or (Hc, Wc) mono, uint8 or uint16 holding
  :attr:`Frame.bits` significant bits (a 12-bit sensor's codes are 0..4095).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from viewcomp.calib.errors import DeviceError, FrameError  # noqa: F401 (re-exported)

#: Control name -> unit. Backends report and take values in these units.
CONTROLS: dict[str, str] = {
    "exposure": "s",
    "gain": "x",
    "white_balance": "K",
    "focus": "driver units",
    "auto_exposure": "0/1",
    "auto_white_balance": "0/1",
    "autofocus": "0/1",
}


@dataclass(frozen=True)
class ControlRange:
    """What a control accepts: ``low`` .. ``high`` in steps of ``step`` (0: continuous), in the
    unit of :data:`CONTROLS`."""

    low: float
    high: float
    step: float = 0.0


@dataclass(frozen=True)
class Frame:
    """One camera frame.

    ``image``: (Hc, Wc, 3) RGB or (Hc, Wc) mono, uint8 or uint16 with ``bits`` significant bits.
    ``timestamp``: clock time (s) at which the exposure *started*; ``exposure`` (s) and ``gain``
    (x) are what the frame was taken with, as the device reports them. ``sequence``: the
    device's frame counter (a gap means dropped frames). ``linear``: True when the codes are
    proportional to light (raw sensor data: DSLR raw, machine vision); False when the camera
    encoded them with its own response (webcams, JPEG), which the capture set's rig.toml
    describes.
    """

    image: np.ndarray
    timestamp: float
    exposure: float
    gain: float
    sequence: int
    bits: int = 8
    linear: bool = False

    @property
    def max_code(self) -> int:
        """The largest code a sample can hold (2**bits - 1)."""
        return (1 << self.bits) - 1


class Clock(Protocol):
    """The time the devices and the procedure share."""

    def now(self) -> float:
        """Seconds (monotonic)."""
        ...

    def sleep(self, seconds: float) -> None:
        """Wait ``seconds`` (>= 0)."""
        ...


class Camera(Protocol):
    """A camera with controls that read back and frames that carry their own timestamps."""

    @property
    def name(self) -> str:
        """What the device is, for messages ("camera 0 (V4L2)", "emulated webcam")."""
        ...

    @property
    def resolution(self) -> tuple[int, int]:
        """(width, height) of the frames in pixels."""
        ...

    @property
    def channels(self) -> int:
        """3 for a colour camera, 1 for a mono one."""
        ...

    def controls(self) -> dict[str, ControlRange]:
        """The controls of :data:`CONTROLS` that this device has, with their ranges."""
        ...

    def get(self, control: str) -> float:
        """The control's value as the device reports it now."""
        ...

    def set(self, control: str, value: float) -> float:
        """Ask for ``value`` and return what the device then reports (drivers round to their
        steps and clamp to their range). Raises :class:`DeviceError` when the device has no
        such control or refuses it."""
        ...

    def grab(self) -> Frame:
        """The next frame the device delivers (drivers queue frames: it may be older than the
        call). Raises :class:`FrameError` for one failed read, :class:`DeviceError` when the
        device is gone."""
        ...

    def close(self) -> None:
        """Release the device."""
        ...


class Projector(Protocol):
    """Shows full-resolution patterns; says when each was handed to the display."""

    @property
    def resolution(self) -> tuple[int, int]:
        """(width, height) in pixels."""
        ...

    @property
    def refresh_hz(self) -> float:
        """The display's refresh rate (frames per second)."""
        ...

    def show(self, image: np.ndarray) -> float:
        """Show (H, W, 3) uint8 RGB until the next call; returns the clock time at which the
        frame was handed to the display (after the buffer swap). The light changes some
        refreshes later (the projector's own latency, unknown here: the procedure measures
        it and checks every frame it keeps)."""
        ...

    def close(self) -> None:
        """Release the window (or whatever stands for it)."""
        ...
