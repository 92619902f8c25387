"""The projector of `viewcomp capture`: a fullscreen window showing each pattern pixel for pixel.

It implements :class:`viewcomp.calib.hw.interface.Projector` with glfw and moderngl: no
scaling, no filtering, vsync on; :meth:`GlfwProjector.show` returns the clock time after the
buffer swap (and a ``glFinish``, so that the swap was submitted, not only queued).
"""

from __future__ import annotations

import numpy as np

from viewcomp.calib.hw.clock import MonotonicClock
from viewcomp.calib.hw.interface import Clock, DeviceError
from viewcomp.rt.gl.context import core_profile_hints
from viewcomp.rt.play.glfw_session import GlfwSession, MonitorInfo
from viewcomp.rt.play.glfw_session import list_monitors as glfw_monitors


def list_monitors() -> list[MonitorInfo]:
    """The monitors GLFW sees: index, name, current mode (width, height, refresh Hz) and
    position of the top-left corner on the desktop.

    Raises:
        DeviceError: no display (or no glfw).
    """
    return glfw_monitors(DeviceError)


class GlfwProjector:
    """A fullscreen window on monitor ``monitor`` (an index of :func:`list_monitors`) that
    shows patterns pixel for pixel at the monitor's current mode. ``clock`` must be the
    capture procedure's (None: :class:`~viewcomp.calib.hw.clock.MonotonicClock`). Use as a
    context manager or call :meth:`close`."""

    def __init__(self, monitor: int, vsync: bool = True, clock: Clock | None = None) -> None:
        self._clock = clock if clock is not None else MonotonicClock()
        self._session = GlfwSession(DeviceError)
        try:
            self._open(monitor, vsync)
        except BaseException:  # undo on any failure, Ctrl-C included; then re-raise
            self._session.close()
            raise

    def _open(self, monitor: int, vsync: bool) -> None:
        glfw = self._session.glfw
        self._glfw = glfw
        monitors = glfw.get_monitors() or []
        if not 0 <= monitor < len(monitors):
            names = ", ".join(f"{m.index}: {m.name}" for m in self._session.monitors()) or "none"
            raise DeviceError(
                f"no monitor {monitor}: GLFW sees {len(monitors)} ({names}); choose one with "
                "--monitor (see --list-monitors)"
            )
        mon = monitors[monitor]
        mode = glfw.get_video_mode(mon)
        self._refresh = float(mode.refresh_rate) if mode.refresh_rate > 0 else 60.0
        core_profile_hints(glfw)
        glfw.window_hint(glfw.AUTO_ICONIFY, False)
        glfw.window_hint(glfw.REFRESH_RATE, mode.refresh_rate)
        self._window = glfw.create_window(
            mode.size.width, mode.size.height, "viewcomp capture", mon, None
        )
        if not self._window:
            raise DeviceError(
                f"cannot open a fullscreen OpenGL 3.3 window on monitor {monitor} "
                f"({self._session.last_error}); fix: install the Debian packages libgl1 "
                "libgl1-mesa-dri (Mesa llvmpipe is enough)"
            )
        glfw.make_context_current(self._window)
        glfw.swap_interval(1 if vsync else 0)
        glfw.set_input_mode(self._window, glfw.CURSOR, glfw.CURSOR_HIDDEN)
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
            self._prog["u_flip_y"].value = 1  # type: ignore[union-attr]  # a uniform: moderngl types members as a union
        self._tex = self._ctx.texture(self._size, 3, dtype="f1", alignment=1)
        self._tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self._vao = self._ctx.vertex_array(self._prog, [])
        self._closed = False

    @property
    def resolution(self) -> tuple[int, int]:
        """(width, height) of the window's framebuffer in pixels."""
        return self._size

    @property
    def refresh_hz(self) -> float:
        """The monitor mode's refresh rate (60 when GLFW does not say)."""
        return self._refresh

    def show(self, image: np.ndarray) -> float:
        """Upload and show one (H, W, 3) uint8 pattern; returns the clock time after the
        buffer swap."""
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
        self._ctx.finish()
        swapped = self._clock.now()
        self._glfw.poll_events()
        return swapped

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
        self._session.close()

    def __enter__(self) -> GlfwProjector:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
