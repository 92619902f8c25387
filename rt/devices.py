"""The projector and the camera of `viewcomp capture`, behind one small interface.

Two protocols, :class:`Projector` and :class:`Camera`, and three implementations:

- :class:`GlfwProjector`: a fullscreen window on a monitor (glfw + moderngl), showing each
  pattern pixel for pixel (no scaling, no filtering), vsync on.
- :class:`OpenCVCamera`: an OpenCV ``VideoCapture`` device, exposure, white balance and focus
  locked where the driver allows (what it refuses is reported, not hidden), frames averaged.
- :class:`SimulatedRig`: both sides over the simulator (:mod:`viewcomp.calib.simcamera`), so
  the capture procedure runs the same code path without hardware, in tests and demos.

Images crossing this interface are numpy RGB, row 0 at the top: the projector takes
(H, W, 3) uint8 at its resolution; the camera returns (Hc, Wc, 3) uint8, or uint16 when it
averaged several 8-bit frames (code c * 257 for the 8-bit mean c: same 0..1 scale).
"""

from __future__ import annotations

import sys
from dataclasses import replace
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from viewcomp.calib.imageio import CaptureError
from viewcomp.rt.context import core_profile_hints

if TYPE_CHECKING:
    from viewcomp.calib.simulator import Screen, Simulator


class DeviceError(CaptureError):
    """A projector or camera that cannot be opened or used; the message says what to do."""


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
# glfw projector


def _glfw() -> Any:
    """The glfw module, initialised, reporting errors as exceptions."""
    try:
        import glfw
    except ImportError as exc:
        raise DeviceError(
            f"cannot load GLFW ({exc}): install the glfw Python package and the GLFW 3 "
            "library (Debian: libglfw3)"
        ) from exc
    glfw.ERROR_REPORTING = "raise"
    try:
        glfw.init()
    except glfw.GLFWError as exc:
        raise DeviceError(
            f"cannot initialise GLFW ({exc}): run on the machine the projector is connected "
            "to, with a display (DISPLAY set)"
        ) from exc
    return glfw


def list_monitors() -> list[dict[str, Any]]:
    """The monitors GLFW sees: index, name, current mode (width, height, refresh Hz) and
    position of the top-left corner on the desktop."""
    glfw = _glfw()
    out = []
    for i, mon in enumerate(glfw.get_monitors()):
        mode = glfw.get_video_mode(mon)
        name = glfw.get_monitor_name(mon)
        out.append(
            {
                "index": i,
                "name": name.decode(errors="replace") if isinstance(name, bytes) else str(name),
                "width": int(mode.size.width),
                "height": int(mode.size.height),
                "refresh_hz": int(mode.refresh_rate),
                "position": tuple(int(v) for v in glfw.get_monitor_pos(mon)),
            }
        )
    return out


class GlfwProjector:
    """A fullscreen window on monitor ``monitor`` (an index of :func:`list_monitors`) that
    shows patterns pixel for pixel at the monitor's current mode. Use as a context manager
    or call :meth:`close`."""

    def __init__(self, monitor: int, vsync: bool = True) -> None:
        glfw = _glfw()
        self._glfw = glfw
        monitors = glfw.get_monitors()
        if not 0 <= monitor < len(monitors):
            names = ", ".join(f"{m['index']}: {m['name']}" for m in list_monitors()) or "none"
            raise DeviceError(
                f"no monitor {monitor}: GLFW sees {len(monitors)} ({names}); choose one with "
                "--monitor (see --list-monitors)"
            )
        mon = monitors[monitor]
        mode = glfw.get_video_mode(mon)
        try:
            core_profile_hints(glfw)
            glfw.window_hint(glfw.AUTO_ICONIFY, False)
            glfw.window_hint(glfw.REFRESH_RATE, mode.refresh_rate)
            self._window = glfw.create_window(
                mode.size.width, mode.size.height, "viewcomp capture", mon, None
            )
            glfw.make_context_current(self._window)
            glfw.swap_interval(1 if vsync else 0)
            glfw.set_input_mode(self._window, glfw.CURSOR, glfw.CURSOR_HIDDEN)
        except glfw.GLFWError as exc:
            raise DeviceError(
                f"cannot open a fullscreen OpenGL 3.3 window on monitor {monitor} ({exc})"
            ) from exc
        import moderngl

        from viewcomp.shaders import build_program

        self._ctx = moderngl.create_context()
        fw, fh = glfw.get_framebuffer_size(self._window)
        self._size = (int(fw), int(fh))
        self._prog = build_program(
            self._ctx,
            "fullscreen.vert.glsl",
            "present.frag.glsl",
        )
        if "u_flip_y" in self._prog:
            self._prog["u_flip_y"].value = 1
        self._tex = self._ctx.texture(self._size, 3, dtype="f1", alignment=1)
        self._tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self._vao = self._ctx.vertex_array(self._prog, [])
        self._closed = False

    @property
    def resolution(self) -> tuple[int, int]:
        """(width, height) of the window's framebuffer in pixels."""
        return self._size

    def show(self, image: np.ndarray) -> None:
        """Upload and show one (H, W, 3) uint8 pattern; returns after the buffer swap."""
        w, h = self._size
        img = np.asarray(image)
        if img.shape != (h, w, 3) or img.dtype != np.uint8:
            raise ValueError(
                f"the projector shows (H, W, 3) uint8 = {(h, w, 3)}, got {img.shape} {img.dtype}"
            )
        if self._closed:
            raise DeviceError("the projector window is closed")
        self._glfw.make_context_current(self._window)
        self._tex.write(np.ascontiguousarray(img).tobytes())
        self._ctx.screen.use()
        self._ctx.viewport = (0, 0, w, h)
        self._tex.use(0)
        self._vao.render(mode=self._ctx.TRIANGLES, vertices=3)
        self._glfw.swap_buffers(self._window)
        self._glfw.poll_events()

    def read_back(self) -> np.ndarray:
        """The window's front content as (H, W, 3) uint8 RGB, row 0 at the top (for tests)."""
        w, h = self._size
        self._glfw.make_context_current(self._window)
        data = self._ctx.screen.read(viewport=(0, 0, w, h), components=3, alignment=1)
        return np.frombuffer(data, np.uint8).reshape(h, w, 3)[::-1].copy()

    def close(self) -> None:
        """Release GL objects and destroy the window."""
        if self._closed:
            return
        self._closed = True
        for obj in (self._vao, self._tex, self._prog):
            obj.release()
        self._ctx.release()
        self._glfw.destroy_window(self._window)

    def __enter__(self) -> GlfwProjector:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


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
    """A simulated projector and camera over :class:`~viewcomp.calib.simcamera.SimCamera`.

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
        from viewcomp.calib.simcamera import SimCamera

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
        from viewcomp.calib.simcamera import SimCamera

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
        lin = self._cam.linear(screen, image)
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

    def close(self) -> None:
        return None
