"""The projector and the camera of `viewcomp capture`, behind one small interface.

Two protocols, :class:`Projector` and :class:`Camera`, and the implementations that need no
GL (the projector window, :class:`viewcomp.rt.play.projector.GlfwProjector`, is GL and lives
with the runtime):
- :class:`OpenCVCamera`: an OpenCV ``VideoCapture`` device, exposure, white balance and focus
  locked where the driver allows (what it refuses is reported, not hidden), frames averaged.
- :class:`SimulatedRig`: both sides over the simulator (:mod:`viewcomp.calib.sim.simcamera`), so
  the capture procedure runs the same code path without hardware, in tests and demos; its
  exposure is a linear gain that can be set (HDR brackets).

Images crossing this interface are numpy RGB, row 0 at the top: the projector takes
(H, W, 3) uint8 at its resolution; the camera returns (Hc, Wc, 3) uint8, or uint16 when it
averaged several 8-bit frames (code c * 257 for the 8-bit mean c: same 0..1 scale).
"""

from __future__ import annotations

import sys
from dataclasses import replace
from typing import TYPE_CHECKING, Protocol

import numpy as np

from viewcomp.calib.hw.interface import DeviceError

if TYPE_CHECKING:
    from viewcomp.calib.sim.simulator import Screen, Simulator


class Projector(Protocol):
    """Shows full-resolution patterns."""

    @property
    def resolution(self) -> tuple[int, int]:
        """(width, height) in pixels."""
        ...

    def show(self, image: np.ndarray) -> None:
        """Show (H, W, 3) uint8 RGB at the projector's resolution until the next call."""
        ...

    def close(self) -> None:
        """Release the window (or whatever stands for it)."""
        ...


class Camera(Protocol):
    """Grabs averaged frames with settings locked."""

    @property
    def resolution(self) -> tuple[int, int]:
        """(width, height) of the frames in pixels."""
        ...

    def lock(self) -> list[str]:
        """Lock exposure, white balance and focus where possible; returns what could not be
        locked, as sentences for the user (empty: everything locked)."""
        ...

    def grab(self, n_frames: int) -> np.ndarray:
        """The mean of ``n_frames`` fresh frames: (Hc, Wc, 3) uint8 or uint16 RGB."""
        ...

    def get_exposure(self) -> float:
        """The exposure the camera reports, in its driver's units."""
        ...

    def set_exposure(self, value: float) -> float:
        """Set the exposure (driver's units) and return what the camera then reports; raises
        :class:`DeviceError` when the camera does not let it be set."""
        ...

    def close(self) -> None:
        """Release the device."""
        ...


def average_frames(frames: list[np.ndarray]) -> np.ndarray:
    """Mean of RGB frames (each (H, W, 3) uint8 or uint16): one 8-bit frame is returned as is;
    several 8-bit frames give uint16 codes round(257 * mean), keeping the extra precision."""
    if not frames:
        raise ValueError("average_frames needs at least one frame")
    first = frames[0]
    if any(f.shape != first.shape or f.dtype != first.dtype for f in frames):
        raise DeviceError("the camera changed its frame size or format between frames")
    if len(frames) == 1:
        return first.copy()
    mean = np.mean(np.stack(frames).astype(np.float64), axis=0)
    if first.dtype == np.uint8:
        return np.rint(mean * 257.0).astype(np.uint16)
    return np.rint(mean).astype(first.dtype)


# ---------------------------------------------------------------------------------------------
# OpenCV camera


class OpenCVCamera:
    """OpenCV ``VideoCapture`` device ``index``, optionally at ``size`` (width, height) and a
    fixed ``exposure`` (the driver's units: CAP_PROP_EXPOSURE). Frames are read after
    ``flush`` stale ones are dropped (drivers buffer frames from before the pattern changed).
    """

    def __init__(
        self,
        index: int,
        size: tuple[int, int] | None = None,
        exposure: float | None = None,
        flush: int = 3,
    ) -> None:
        import cv2

        self._cv2 = cv2
        self.index = index
        self.exposure = exposure
        self.flush = max(0, int(flush))
        self._cap = cv2.VideoCapture(index)
        if not self._cap.isOpened():
            raise DeviceError(
                f"cannot open camera {index}: check that it is connected and not used by "
                "another program, and choose it with --camera N (0 is the first)"
            )
        if size is not None:
            self._cap.set(cv2.CAP_PROP_FRAME_WIDTH, size[0])
            self._cap.set(cv2.CAP_PROP_FRAME_HEIGHT, size[1])
        self._cap.set(cv2.CAP_PROP_BUFFERSIZE, 1)
        frame = self._read()
        self._size = (int(frame.shape[1]), int(frame.shape[0]))
        if size is not None and self._size != tuple(size):
            print(
                f"camera {index}: asked for {size[0]}x{size[1]}, the driver delivers "
                f"{self._size[0]}x{self._size[1]}",
                file=sys.stderr,
            )

    @property
    def resolution(self) -> tuple[int, int]:
        """(width, height) of the frames the driver delivers."""
        return self._size

    def _try(self, prop: int, values: tuple[float, ...]) -> bool:
        """Set ``prop`` to the first of ``values`` that the driver accepts and reports back."""
        for v in values:
            if self._cap.set(prop, v) and abs(self._cap.get(prop) - v) < 1e-6:
                return True
        return False

    def lock(self) -> list[str]:
        """Switch off auto exposure, auto white balance and autofocus where the driver lets
        us; set ``exposure`` if given. Returns what could not be locked."""
        cv2 = self._cv2
        problems = []
        # V4L2 takes 1 (manual) / 3 (auto); other backends the legacy 0.25 / 0.75
        if not self._try(cv2.CAP_PROP_AUTO_EXPOSURE, (1.0, 0.25)):
            problems.append(
                "auto exposure could not be switched off: brightness may drift between "
                "captures (lock it in the camera's own tool, e.g. v4l2-ctl or guvcview)"
            )
        if self.exposure is not None and not self._try(cv2.CAP_PROP_EXPOSURE, (self.exposure,)):
            problems.append(f"the exposure could not be set to {self.exposure}")
        temperature = self._cap.get(cv2.CAP_PROP_WB_TEMPERATURE)
        if not self._try(cv2.CAP_PROP_AUTO_WB, (0.0,)):
            problems.append(
                "auto white balance could not be switched off: colours may drift between "
                "captures (lock it in the camera's own tool)"
            )
        elif temperature > 0:
            self._cap.set(cv2.CAP_PROP_WB_TEMPERATURE, temperature)
        if not self._try(cv2.CAP_PROP_AUTOFOCUS, (0.0,)):
            problems.append("autofocus could not be switched off (fine for fixed-focus cameras)")
        return problems

    def get_exposure(self) -> float:
        """CAP_PROP_EXPOSURE as the driver reports it (V4L2: units of 100 us; DirectShow and
        MSMF: log2 of seconds, <= 0)."""
        return float(self._cap.get(self._cv2.CAP_PROP_EXPOSURE))

    def set_exposure(self, value: float) -> float:
        """Set CAP_PROP_EXPOSURE, drop ``flush`` frames taken before it applied, and return
        what the driver then reports (drivers round to their own steps and range)."""
        if not self._cap.set(self._cv2.CAP_PROP_EXPOSURE, float(value)):
            raise DeviceError(
                f"camera {self.index}: the driver refuses to set the exposure (CAP_PROP_EXPOSURE "
                f"= {value:g}): --hdr needs a camera whose exposure OpenCV can set; capture "
                "without --hdr (at an exposure where nothing clips), or use another camera"
            )
        for _ in range(self.flush):
            self._read()
        return self.get_exposure()

    def _read(self) -> np.ndarray:
        ok, frame = self._cap.read()
        if not ok or frame is None:
            raise DeviceError(
                f"camera {self.index} delivered no frame: check the connection and that no "
                "other program uses it"
            )
        if frame.ndim == 2:
            frame = np.repeat(frame[:, :, None], 3, axis=2)
        return np.ascontiguousarray(frame[:, :, 2::-1])  # BGR -> RGB

    def grab(self, n_frames: int) -> np.ndarray:
        """Drop ``flush`` buffered frames, then average ``n_frames`` fresh ones."""
        if n_frames < 1:
            raise ValueError(f"n_frames must be >= 1, got {n_frames}")
        for _ in range(self.flush):
            self._read()
        return average_frames([self._read() for _ in range(n_frames)])

    def close(self) -> None:
        """Release the device."""
        self._cap.release()

    def __enter__(self) -> OpenCVCamera:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


# ---------------------------------------------------------------------------------------------
# The simulated rig


class SimulatedRig:
    """A simulated projector and camera over :class:`~viewcomp.calib.sim.simcamera.SimCamera`.

    ``screens`` maps the screens the procedure asks for (``"white"``, ``"screen"``) to
    simulator screens; :meth:`use_screen` swaps them (what the user does by hand). The
    :attr:`projector` and :attr:`camera` attributes implement the two protocols. For tests,
    :meth:`move_camera_after` moves the camera after a number of grabs, and
    ``projector_visible=False`` stands for a projector on the wrong monitor.
    """

    def __init__(
        self,
        sim: Simulator,
        screens: dict[str, Screen],
        projector_visible: bool = True,
    ) -> None:
        from viewcomp.calib.sim.simcamera import SimCamera

        self.sim = sim
        self.screens = dict(screens)
        self.projector_visible = projector_visible
        self._cam = SimCamera(sim)
        w, h = sim.rig.projector.resolution
        self._image = np.zeros((h, w, 3), np.uint8)
        self._screen_name = next(iter(self.screens))
        self._grabs = 0
        self._move: tuple[int, tuple[float, float, float]] | None = None
        self._noise_sims: dict[int, Simulator] = {}
        #: The camera's exposure now (a linear gain; starts at the simulator's): what
        #: ``camera.set_exposure`` sets.
        self.exposure = float(sim.camera.exposure)
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

    def move_camera_after(self, grabs: int, offset: tuple[float, float, float]) -> None:
        """After ``grabs`` more grabs, move the camera by ``offset`` metres (a bumped tripod)."""
        self._move = (self._grabs + grabs, offset)

    def _grab(self, n_frames: int) -> np.ndarray:
        from viewcomp.calib.sim.simcamera import SimCamera

        if self._move is not None and self._grabs >= self._move[0]:
            rig = self.sim.rig
            d = np.asarray(self._move[1], np.float64)
            pos = tuple(float(v) for v in np.asarray(rig.camera.position) + d)
            look = tuple(float(v) for v in np.asarray(rig.camera.look_at) + d)
            rig = replace(rig, camera=replace(rig.camera, position=pos, look_at=look))
            self.sim = self.sim.with_rig(rig)
            self._cam = SimCamera(self.sim)
            self._noise_sims.clear()
            self._move = None
        self._grabs += 1
        screen = self.screens[self._screen_name]
        image = self._image if self.projector_visible else np.zeros_like(self._image)
        lin = self._cam.linear(screen, image) * np.float32(self.exposure / self.sim.camera.exposure)
        noisy = self._noise_sim(n_frames).noise(lin, f"{self._screen_name}/grab{self._grabs}")
        return self.sim.quantise(noisy)

    def _noise_sim(self, n_frames: int) -> Simulator:
        """The simulator with noise averaged over ``n_frames`` frames."""
        if n_frames not in self._noise_sims:
            cam = replace(self.sim.camera, frames=max(1, int(n_frames)))
            self._noise_sims[n_frames] = replace(self.sim, camera=cam)
        return self._noise_sims[n_frames]


class _SimProjector:
    """The projector side of a :class:`SimulatedRig` (the :class:`Projector` protocol)."""

    def __init__(self, rig: SimulatedRig) -> None:
        self._rig = rig

    @property
    def resolution(self) -> tuple[int, int]:
        return self._rig.sim.rig.projector.resolution

    def show(self, image: np.ndarray) -> None:
        w, h = self.resolution
        img = np.asarray(image)
        if img.shape != (h, w, 3) or img.dtype != np.uint8:
            raise ValueError(
                f"the projector shows (H, W, 3) uint8 = {(h, w, 3)}, got {img.shape} {img.dtype}"
            )
        self._rig._image = img.copy()

    def close(self) -> None:
        return None


class _SimCamera:
    """The camera side of a :class:`SimulatedRig` (the :class:`Camera` protocol): nothing to
    lock; ``grab(n)`` renders once with the noise of n averaged frames."""

    def __init__(self, rig: SimulatedRig) -> None:
        self._rig = rig

    @property
    def resolution(self) -> tuple[int, int]:
        return self._rig.sim.rig.camera.resolution

    def lock(self) -> list[str]:
        return []

    def grab(self, n_frames: int) -> np.ndarray:
        if n_frames < 1:
            raise ValueError(f"n_frames must be >= 1, got {n_frames}")
        return self._rig._grab(n_frames)

    def get_exposure(self) -> float:
        return self._rig.exposure

    def set_exposure(self, value: float) -> float:
        if not (np.isfinite(value) and value > 0):
            raise DeviceError(f"the simulated camera's exposure is a gain > 0, got {value}")
        self._rig.exposure = float(value)
        return self._rig.exposure

    def close(self) -> None:
        return None
