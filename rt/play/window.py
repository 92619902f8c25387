"""The window and GL life cycle of `viewcomp play`: signals, the glfw window and its GL
context, the renderer, the input threads and audio, the viewport, and their release.

Rendering happens at the calibration grid's resolution (what the projector's pixels are);
a window of another size gets the grid scaled to fit (linear blit, black bars).
"""

from __future__ import annotations

import logging
import queue
import signal
import socket
import threading
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from viewcomp.calib.errors import PlayerError
from viewcomp.rt.gl.context import core_profile_hints
from viewcomp.rt.gl.egl_suspend import EglSuspend
from viewcomp.rt.media.audio import AudioPlayer, open_alsa
from viewcomp.rt.play.glfw_session import GlfwSession, MonitorInfo
from viewcomp.rt.play.glfw_session import list_monitors as glfw_monitors
from viewcomp.rt.play.live import InputHub, LineReader, OscListener
from viewcomp.rt.play.overlay import Overlay

if TYPE_CHECKING:
    from viewcomp.calib.fit.calibrate import Calibration
    from viewcomp.rt.play.embed import LiveRenderer
    from viewcomp.rt.play.player_options import PlayerOptions
    from viewcomp.rt.play.player_status import PlayerStats

log = logging.getLogger(__name__)


def list_monitors() -> list[MonitorInfo]:
    """The connected monitors (index 0 is the primary).

    Raises:
        PlayerError: no display.
    """
    return glfw_monitors(PlayerError)


class WindowLifecycle:
    """Opening and closing everything :class:`~viewcomp.rt.play.player.Player` runs on (a
    mixin; main thread)."""

    cal: Calibration
    options: PlayerOptions
    hub: InputHub
    stats: PlayerStats
    renderer: LiveRenderer | None
    osc_address: tuple[str, int] | None
    _stop: threading.Event
    _vq: queue.Queue[Any]
    _glfw: GlfwSession | None
    _egl: EglSuspend | None
    _win: Any
    _ctx: Any
    _overlay: Overlay | None
    _threads: list[Any]
    _audio: AudioPlayer | None
    _pump_thread: threading.Thread | None
    _osc: OscListener | None
    _sock: socket.socket | None
    _fb_size: tuple[int, int]
    _viewport: tuple[int, int, int, int]

    if TYPE_CHECKING:  # the player's own, declared for the type checker

        def stop(self) -> None: ...

        def _pump(self) -> None: ...

        def _on_key(self, win: Any, key: int, scancode: int, action: int, mods: int) -> None: ...

        def _on_mouse_button(self, win: Any, button: int, action: int, mods: int) -> None: ...

        def _on_cursor(self, win: Any, x: float, y: float) -> None: ...

        def _watch_display(self, monitor: Any) -> None: ...

        def _unwatch_display(self) -> None: ...

    def _init_window(self) -> None:
        self.osc_address = None
        self._glfw = None
        self._egl = None
        self._win = None
        self._ctx = None
        self._overlay = None
        self._threads = []
        self._audio = None
        self._fb_size = (0, 0)
        self._viewport = (0, 0, 0, 0)

    def read_window(self) -> np.ndarray:
        """The grid's viewport of the window's back buffer as (H, W, 3) uint8, row 0 on top.

        Call from ``on_frame`` (before the swap) to see exactly what is about to be shown.
        """
        x, y, w, h = self._viewport
        data = self._ctx.screen.read(viewport=(x, y, w, h), components=3, alignment=1)
        return np.ascontiguousarray(np.frombuffer(data, np.uint8).reshape(h, w, 3)[::-1])

    def _install_signals(self) -> Callable[[], None]:
        if threading.current_thread() is not threading.main_thread():
            return lambda: None
        old = {s: signal.getsignal(s) for s in (signal.SIGTERM, signal.SIGINT)}

        def handler(signum: int, frame: object) -> None:
            log.info("signal %d: stopping", signum)
            self.stop()

        for s in old:
            signal.signal(s, handler)

        def restore() -> None:
            for s, h in old.items():
                signal.signal(s, h)

        return restore

    def _open_window(self) -> None:
        import glfw
        import moderngl

        from viewcomp.rt.play.embed import LiveRenderer

        o = self.options
        self._egl = EglSuspend()
        self._glfw = GlfwSession(PlayerError)
        monitor = None
        if o.windowed:
            w, h = o.size or (self.cal.shape[1], self.cal.shape[0])
        else:
            monitors = glfw.get_monitors() or []
            if not 0 <= o.monitor < len(monitors):
                listing = "\n".join(f"  {m}" for m in self._glfw.monitors()) or "  (none)"
                raise PlayerError(
                    f"no monitor {o.monitor}; the monitors are:\n{listing}\n"
                    "fix: --monitor N with one of these, or --windowed"
                )
            monitor = monitors[o.monitor]
            mode = glfw.get_video_mode(monitor)
            w, h = o.size or (int(mode.size.width), int(mode.size.height))
            glfw.window_hint(glfw.REFRESH_RATE, int(mode.refresh_rate))
            glfw.window_hint(glfw.AUTO_ICONIFY, False)
        core_profile_hints(glfw)
        glfw.window_hint(glfw.DOUBLEBUFFER, True)
        glfw.window_hint(glfw.RESIZABLE, o.windowed)
        win = glfw.create_window(int(w), int(h), o.title, monitor, None)
        if not win:
            raise PlayerError(
                f"cannot create a {w}x{h} OpenGL 3.3 window "
                f"({self._glfw.last_error}); fix: install the Debian packages "
                "libgl1 libgl1-mesa-dri (Mesa llvmpipe is enough)"
            )
        self._win = win
        glfw.make_context_current(win)
        glfw.swap_interval(1 if o.vsync else 0)
        if monitor is not None:
            glfw.set_input_mode(win, glfw.CURSOR, glfw.CURSOR_HIDDEN)
            self._watch_display(monitor)  # a projector switched off and on: played through
        self._ctx = moderngl.create_context(require=330)
        self.renderer = LiveRenderer(
            self.cal,
            self._ctx,
            method=o.method,
            lam=o.lam,
            tone=o.tone,
            tone_tau=o.tone_tau,
            eye_tau=o.eye_tau,
            angle=o.angle,
            eye=o.eye,
            audience=o.audience,
            async_tone=True,
            tone_hz=o.tone_hz,
            tone_side=o.tone_side,
            scale=o.scale,  # type: ignore[arg-type]
            proc_address=lambda name: int(glfw.get_proc_address(name) or 0),
        )
        self.renderer.eye_state.norm_range = o.norm_range
        self.renderer.warm_up(planes=True, present=self._viewport_needs_scaling(w, h))
        self._overlay = Overlay(self._ctx)
        glfw.set_key_callback(win, self._on_key)
        glfw.set_mouse_button_callback(win, self._on_mouse_button)
        glfw.set_cursor_pos_callback(win, self._on_cursor)
        self._update_viewport()
        log.info(
            "window %dx%d on %s, grid %dx%d, viewport %s",
            *self._fb_size,
            "a window" if monitor is None else f"monitor {o.monitor}",
            *self.renderer.grid,
            self._viewport,
        )

    def _viewport_needs_scaling(self, w: int, h: int) -> bool:
        assert self.renderer is not None
        return (int(w), int(h)) != self.renderer.grid

    def _update_viewport(self) -> None:
        from viewcomp.rt.play.embed_present import fit_viewport

        assert self.renderer is not None
        fb = tuple(int(v) for v in self._glfw.glfw.get_framebuffer_size(self._win))  # type: ignore[union-attr]
        if fb != self._fb_size:
            self._fb_size = fb  # type: ignore[assignment]
            self._viewport = fit_viewport(self.renderer.grid, self._fb_size)

    def _start_threads(self) -> None:
        o = self.options
        if o.osc is not None:
            listener = OscListener(self.hub, *o.osc).start()
            self.osc_address = listener.address
            self._osc = listener
            self._threads.append(listener)
            log.info("listening for OSC on %s:%d", *listener.address)
        if o.stdin_fd is not None:
            self._threads.append(LineReader(self.hub, o.stdin_fd).start())
        for source in o.inputs:  # e.g. the face tracker of --track-camera
            self._threads.append(source.start(self.hub))
        if o.audio:
            out = open_alsa(o.audio_device)
            if out is not None:
                self._audio = AudioPlayer(out)
                self.stats.audio_device = o.audio_device
        self._pump_thread = threading.Thread(target=self._pump, name="viewcomp-pump", daemon=True)
        self._pump_thread.start()

    def _shutdown(self) -> None:
        self._stop.set()
        if self._pump_thread is not None:
            while self._pump_thread.is_alive():
                try:  # unblock a pump waiting on a full queue
                    self._vq.get_nowait()
                except queue.Empty:
                    pass
                self._pump_thread.join(timeout=0.1)
        for t in self._threads:
            t.stop()
        if self._sock is not None:
            self._sock.close()
        if self._audio is not None:
            self._audio.stop()
            self.stats.audio = self._audio.stats
        if self._overlay is not None:
            self._overlay.release()
        if self.renderer is not None:
            self.renderer.release()
        if self._ctx is not None:
            self._ctx.release()
        if self._win is not None and self._glfw is not None:
            self._unwatch_display()
            self._glfw.glfw.destroy_window(self._win)
            self._win = None
        if self._glfw is not None:
            self._glfw.close()
        if self._egl is not None:
            self._egl.restore()

    def _idle(self, seconds: float) -> None:
        if seconds > 0.0005:
            self._glfw.glfw.wait_events_timeout(seconds)  # type: ignore[union-attr]
        else:
            self._glfw.glfw.poll_events()  # type: ignore[union-attr]
