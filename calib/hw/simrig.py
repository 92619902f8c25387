"""The simulated projector and camera behind `viewcomp capture --simulate` and the tests.

:class:`SimulatedRig` implements :class:`~viewcomp.calib.hw.interface.Projector` and
:class:`~viewcomp.calib.hw.interface.Camera` over the camera-space simulator
(:mod:`viewcomp.calib.sim.simcamera`), on a :class:`~viewcomp.calib.hw.clock.SimClock` that
advances as the devices would take time, with the behaviour the capture procedure must cope
with on real devices:

- the projector swaps on its refresh (``refresh_hz``) and the light changes ``latency``
  seconds after the swap;
- the camera free-runs at ``fps`` (slower when the exposure is longer than a frame), each
  frame integrating the light over its exposure (a pattern change during it blends the two);
  the driver keeps the last ``queue`` (>= 1) finished frames, so a grab may return a frame
  older than the call;
- controls take effect at the next frame start and read back; the automatic modes start on,
  and can refuse to switch off (``lockable=False``);
- reads can fail (``fail_reads``: the grab numbers that raise FrameError) and the device can
  die (``dead_after``: grabs after which every read raises DeviceError);
- ``channels=1``: a mono camera (the mean of the three channels' light).

Exposure is in seconds: ``unit_exposure`` seconds (default 1) at gain 1 give the simulator's
unit exposure, and the camera starts at ``CameraPhysics.exposure`` units (default 0.8 s).
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from viewcomp.calib.hw.clock import SimClock
from viewcomp.calib.hw.interface import ControlRange, DeviceError, Frame, FrameError

if TYPE_CHECKING:
    from viewcomp.calib.sim.simulator import Screen, Simulator

AUTO_CONTROLS = ("auto_exposure", "auto_white_balance")


class SimulatedRig:
    """A simulated projector (:attr:`projector`) and camera (:attr:`camera`) on one clock.

    ``screens`` maps the screens the procedure asks for (``"white"``, ``"screen"``) to
    simulator screens; :meth:`use_screen` swaps them (what the user does by hand).
    ``projector_visible=False`` stands for a projector on the wrong monitor;
    :meth:`move_camera_during` for a bumped tripod. See the module doc for the rest.
    """

    def __init__(
        self,
        sim: Simulator,
        screens: dict[str, Screen],
        projector_visible: bool = True,
        clock: SimClock | None = None,
        latency: float = 0.05,
        refresh_hz: float = 120.0,
        fps: float = 30.0,
        queue: int = 2,
        channels: int = 3,
        lockable: bool = True,
        fail_reads: tuple[int, ...] = (),
        dead_after: int | None = None,
        unit_exposure: float = 1.0,
    ) -> None:
        from viewcomp.calib.sim.simcamera import SimCamera

        if channels not in (1, 3):
            raise ValueError(f"channels is 1 (mono) or 3, got {channels}")
        self.sim = sim
        self.screens = dict(screens)
        self.projector_visible = projector_visible
        self.clock = clock if clock is not None else SimClock()
        self.latency = float(latency)
        self.refresh_hz = float(refresh_hz)
        self.fps = float(fps)
        self.queue = max(1, int(queue))
        self.channels = channels
        self.lockable = lockable
        self.fail_reads = set(fail_reads)
        self.dead_after = dead_after
        self.unit_exposure = float(unit_exposure)
        self._cam = SimCamera(sim)
        self._noise_sim = replace(sim, camera=replace(sim.camera, frames=1))
        w, h = sim.rig.projector.resolution
        black = np.zeros((h, w, 3), np.uint8)
        # (time the light changes, image): what the screen shows from then on
        self._shown: list[tuple[float, np.ndarray, int]] = [(-math.inf, black, 0)]
        self._renders: dict[tuple[int, str, int], np.ndarray] = {}
        self._screen_name = next(iter(self.screens))
        self._grabs = 0
        self._moves = 0
        self._move: tuple[str, int, tuple[float, float, float]] | None = None
        self._shows_on_screen = 0
        self.controls: dict[str, float] = {
            "exposure": float(sim.camera.exposure) * self.unit_exposure,
            "gain": 1.0,
            "auto_exposure": 1.0,
            "auto_white_balance": 1.0,
        }
        # (time from which it applies, exposure, gain); frames take the one at their start
        self._settings: list[tuple[float, float, float]] = [
            (-math.inf, self.controls["exposure"], 1.0)
        ]
        self._next_start = self.clock.now()
        self._done: list[tuple[float, float, float, int]] = []  # (start, exposure, gain, seq)
        self._seq = 0
        self.projector = _SimProjector(self)
        self.camera = _SimCamera(self)

    @property
    def screen_name(self) -> str:
        """The name of the screen in front of the projector."""
        return self._screen_name

    def use_screen(self, name: str) -> None:
        """Put screen ``name`` (a key of ``screens``) in place."""
        if name not in self.screens:
            raise ValueError(f"no simulated screen {name!r}; have {', '.join(self.screens)}")
        self._screen_name = name
        self._shows_on_screen = 0

    def move_camera_during(
        self, screen: str, after_shows: int, offset: tuple[float, float, float]
    ) -> None:
        """Move the camera by ``offset`` metres (a bumped tripod) once ``after_shows`` patterns
        have been shown with screen ``screen`` in place."""
        self._move = (screen, after_shows, offset)

    # -- the projector side -----------------------------------------------------------------

    def _show(self, image: np.ndarray) -> float:
        w, h = self.sim.rig.projector.resolution
        img = np.asarray(image)
        if img.shape != (h, w, 3) or img.dtype != np.uint8:
            raise ValueError(
                f"the projector shows (H, W, 3) uint8 = {(h, w, 3)}, got {img.shape} {img.dtype}"
            )
        # the swap waits for the next refresh
        period = 1.0 / self.refresh_hz
        now = self.clock.now()
        self.clock.advance_to(math.ceil(now / period - 1e-9) * period)
        swap = self.clock.now()
        self._shown.append((swap + self.latency, img.copy(), self._shown[-1][2] + 1))
        del self._shown[:-8]
        self._shows_on_screen += 1
        if self._move is not None:
            screen, after, offset = self._move
            if screen == self._screen_name and self._shows_on_screen > after:
                self._move_camera(offset)
                self._move = None
        return swap

    def _move_camera(self, offset: tuple[float, float, float]) -> None:
        from viewcomp.calib.sim.simcamera import SimCamera

        rig = self.sim.rig
        d = np.asarray(offset, np.float64)
        px, py, pz = (float(v) for v in np.asarray(rig.camera.position) + d)
        lx, ly, lz = (float(v) for v in np.asarray(rig.camera.look_at) + d)
        pos, look = (px, py, pz), (lx, ly, lz)
        self.sim = self.sim.with_rig(
            replace(rig, camera=replace(rig.camera, position=pos, look_at=look))
        )
        self._cam = SimCamera(self.sim)
        self._renders.clear()
        self._moves += 1

    # -- the camera side --------------------------------------------------------------------

    def _setting_at(self, t: float) -> tuple[float, float]:
        for start, exposure, gain in reversed(self._settings):
            if start <= t:
                return exposure, gain
        return self._settings[0][1], self._settings[0][2]

    def _run_until(self, now: float) -> None:
        """Finish every frame whose exposure ends by ``now``; the driver keeps the last
        ``queue`` of them."""
        while True:
            exposure, gain = self._setting_at(self._next_start)
            if self._next_start + exposure > now:
                break
            self._seq += 1
            self._done.append((self._next_start, exposure, gain, self._seq))
            self._next_start += max(1.0 / self.fps, exposure)
        del self._done[: max(0, len(self._done) - self.queue)]

    def _grab(self) -> Frame:
        self._grabs += 1
        if self.dead_after is not None and self._grabs > self.dead_after:
            raise DeviceError("simulated camera: the device is gone (unplugged)")
        self._run_until(self.clock.now())
        if not self._done:
            exposure, _ = self._setting_at(self._next_start)
            self.clock.advance_to(self._next_start + exposure)
            self._run_until(self.clock.now())
        start, exposure, gain, seq = self._done.pop(0)
        if self._grabs in self.fail_reads:
            raise FrameError(f"simulated camera: read {self._grabs} failed (a dropped transfer)")
        units = exposure * gain / (self.unit_exposure * self.sim.camera.exposure)
        lin = self._light(start, exposure) * np.float32(units)
        noisy = self._noise_sim.noise(lin, f"{self._screen_name}/grab{self._grabs}")
        if self.channels == 1:
            noisy = noisy.mean(axis=2)
        image = self.sim.quantise(noisy)
        return Frame(
            image=image,
            timestamp=start,
            exposure=exposure,
            gain=gain,
            sequence=seq,
            bits=self.sim.camera.bits,
            linear=self.sim.response.kind == "linear",
        )

    def _light(self, start: float, exposure: float) -> np.ndarray:
        """The camera's linear signal at the simulator's exposure, averaged over the light
        the screen sends during [start, start + exposure]."""
        end = start + max(exposure, 1e-9)
        total: np.ndarray | None = None
        for i, (t0, _img, _n) in enumerate(self._shown):
            t1 = self._shown[i + 1][0] if i + 1 < len(self._shown) else math.inf
            overlap = min(end, t1) - max(start, t0)
            if overlap <= 0:
                continue
            part = self._render(i) * np.float32(overlap / (end - start))
            total = part if total is None else total + part
        assert total is not None
        return total

    def _render(self, i: int) -> np.ndarray:
        _t0, img, n = self._shown[i]
        key = (n, self._screen_name, self._moves)
        if key not in self._renders:
            if len(self._renders) > 6:
                self._renders.pop(next(iter(self._renders)))
            shown = img if self.projector_visible else np.zeros_like(img)
            self._renders[key] = self._cam.linear(self.screens[self._screen_name], shown)
        return self._renders[key]

    def _set(self, control: str, value: float) -> float:
        if control not in self.controls:
            raise DeviceError(f"simulated camera: no control {control!r}")
        v = float(value)
        if not math.isfinite(v):
            raise DeviceError(f"simulated camera: {control} = {value} is not a number")
        rng = _CONTROL_RANGES[control]
        v = min(max(v, rng.low), rng.high)
        if control in AUTO_CONTROLS:
            v = float(round(v))
            if v == 0 and not self.lockable:
                raise DeviceError(f"simulated camera: the driver refuses to switch {control} off")
        self.controls[control] = v
        if control in ("exposure", "gain"):
            # applies from the next frame start on
            self._run_until(self.clock.now())
            self._settings.append(
                (self._next_start, self.controls["exposure"], self.controls["gain"])
            )
            del self._settings[:-8]
        return v


_CONTROL_RANGES = {
    "exposure": ControlRange(1e-4, 60.0),
    "gain": ControlRange(1.0, 16.0),
    "auto_exposure": ControlRange(0.0, 1.0, 1.0),
    "auto_white_balance": ControlRange(0.0, 1.0, 1.0),
}


class _SimProjector:
    """The projector side of a :class:`SimulatedRig`."""

    def __init__(self, rig: SimulatedRig) -> None:
        self._rig = rig

    @property
    def resolution(self) -> tuple[int, int]:
        return self._rig.sim.rig.projector.resolution

    @property
    def refresh_hz(self) -> float:
        return self._rig.refresh_hz

    def show(self, image: np.ndarray) -> float:
        return self._rig._show(image)

    def close(self) -> None:
        return None


class _SimCamera:
    """The camera side of a :class:`SimulatedRig`."""

    def __init__(self, rig: SimulatedRig) -> None:
        self._rig = rig

    @property
    def name(self) -> str:
        return "simulated camera" + (" (mono)" if self._rig.channels == 1 else "")

    @property
    def resolution(self) -> tuple[int, int]:
        return self._rig.sim.rig.camera.resolution

    @property
    def channels(self) -> int:
        return self._rig.channels

    def controls(self) -> dict[str, ControlRange]:
        return dict(_CONTROL_RANGES)

    def get(self, control: str) -> float:
        if control not in self._rig.controls:
            raise DeviceError(f"simulated camera: no control {control!r}")
        return self._rig.controls[control]

    def set(self, control: str, value: float) -> float:
        return self._rig._set(control, value)

    def grab(self) -> Frame:
        return self._rig._grab()

    def close(self) -> None:
        return None
