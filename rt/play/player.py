"""`viewcomp play`: fullscreen playback with a live viewing angle (glfw window, GL 3.3).

Threads and who owns what:

- main thread: the glfw window, the GL context and every GL object (through
  :class:`~viewcomp.rt.play.embed.LiveRenderer`), input callbacks, the clock, presentation;
- ``viewcomp-pump``: walks the playlist, opens each file with
  :class:`~viewcomp.rt.media.video.VideoReader` (its own decode thread and bounded queue, frames
  fitted to the projector grid) and forwards frames to a bounded queue and audio to the
  :class:`~viewcomp.rt.media.audio.AudioPlayer`;
- ``viewcomp-tone``: the tone map (and the paper method's model) for the newest frame;
- ``viewcomp-osc`` / ``viewcomp-stdin``: live eye input (:mod:`viewcomp.rt.play.live`);
- ``viewcomp-audio``: writes audio to the device, on the wall clock.

Timing: the wall clock (``time.monotonic``) leads. File k's frame at time t is due at
``origin_k + t``; origin_k is where file k-1 ended (or now, if that has passed). A frame is
drawn when it is due within the render time (running estimate), presented (buffer swap) at
its due time, and dropped unrendered when its slot (due .. due + 1/rate) has passed: late
frames never accumulate and the picture never drifts. With vsync the swap waits for the
display's next refresh. Audio chunks are due on the same clock (see ``rt/audio.py``).

Rendering happens at the calibration grid's resolution (what the projector's pixels are);
a window of another size gets the grid scaled to fit (linear blit, black bars).
"""

from __future__ import annotations

import ctypes
import logging
import math
import os
import queue
import signal
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from viewcomp.calib.comp.tonemap import DEFAULT_LAMBDA
from viewcomp.rt.gl.context import core_profile_hints, libegl
from viewcomp.rt.media.audio import AudioPlayer, AudioStats, open_alsa
from viewcomp.rt.media.frames import Planes
from viewcomp.rt.media.video import VideoError, VideoReader
from viewcomp.rt.play.glfw_session import GlfwSession, MonitorInfo
from viewcomp.rt.play.glfw_session import list_monitors as glfw_monitors
from viewcomp.rt.play.live import (
    InputHub,
    LineReader,
    NudgeAngle,
    OscListener,
    SetAngle,
    SourceCounts,
    eye_to_polar,
)

if TYPE_CHECKING:
    from viewcomp.calib.fit.calibrate import Calibration
    from viewcomp.rt.play.embed import FrameRecord, LiveRenderer

log = logging.getLogger(__name__)

VIDEO_SUFFIXES = {
    ".mp4", ".mkv", ".mov", ".avi", ".webm", ".m4v", ".mpg", ".mpeg", ".ts", ".m2ts", ".ogv",
    ".wmv", ".flv",
}  # fmt: skip


class PlayerError(RuntimeError):
    """Playback cannot start (no display, no such monitor, empty playlist); says why."""


# ----------------------------------------------------------------------- playlist
def expand_playlist(paths: Sequence[str | os.PathLike[str]]) -> list[Path]:
    """Files as given, folders expanded to their video files (by extension, sorted by name).

    Raises:
        PlayerError: a path that does not exist, or nothing to play.
    """
    out: list[Path] = []
    for raw in paths:
        p = Path(raw)
        if p.is_dir():
            found = sorted(
                (q for q in p.iterdir() if q.is_file() and not q.name.startswith(".")
                 and q.suffix.lower() in VIDEO_SUFFIXES),
                key=lambda q: q.name.lower(),
            )  # fmt: skip
            if not found:
                raise PlayerError(
                    f"folder {p} has no video files ({', '.join(sorted(VIDEO_SUFFIXES))})"
                )
            out.extend(found)
        elif p.is_file():
            out.append(p)
        else:
            raise PlayerError(f"no such file or folder: {p}")
    if not out:
        raise PlayerError("nothing to play: give a video file, several, or a folder")
    return out


# ----------------------------------------------------------------------- monitors
class _EglSuspend:
    """Releases an EGL context current on this thread, and makes it current again later.

    A GLX context (the window's) cannot become current while an EGL one is (X error
    BadAccess, fatal): a process that also renders headless through
    :func:`viewcomp.rt.gl.context.create_context` on this thread gets its context back after
    playback.
    """

    _EGL_DRAW, _EGL_READ = 0x3059, 0x305A

    def __init__(self) -> None:
        self._saved: tuple[int, int, int, int] | None = None
        self._lib: Any = None
        try:
            lib = libegl()
        except OSError:
            return
        for name in ("eglGetCurrentDisplay", "eglGetCurrentContext", "eglGetCurrentSurface"):
            getattr(lib, name).restype = ctypes.c_void_p
        lib.eglGetCurrentSurface.argtypes = [ctypes.c_int]
        lib.eglMakeCurrent.argtypes = [ctypes.c_void_p] * 4
        context = lib.eglGetCurrentContext()
        if not context:
            return
        display = lib.eglGetCurrentDisplay()
        draw = lib.eglGetCurrentSurface(self._EGL_DRAW)
        read = lib.eglGetCurrentSurface(self._EGL_READ)
        lib.eglMakeCurrent(display, None, None, None)
        self._lib, self._saved = lib, (display, draw, read, context)

    def restore(self) -> None:
        """Make the released context current again (idempotent)."""
        if self._saved is not None:
            if not self._lib.eglMakeCurrent(*self._saved):  # e.g. destroyed meanwhile
                log.debug("could not make the previous EGL context current again")
            self._saved = None


def list_monitors() -> list[MonitorInfo]:
    """The connected monitors (index 0 is the primary).

    Raises:
        PlayerError: no display.
    """
    return glfw_monitors(PlayerError)


# ----------------------------------------------------------------------- options, stats
@dataclass
class PlayerOptions:
    """How to play. Angles in degrees, eye in metres, times in seconds.

    ``stdin_fd`` is the descriptor command lines are read from (None: no line input);
    ``osc`` (host, port) to listen on (None: no OSC; port 0: any free port, see
    :attr:`Player.osc_address`); ``max_seconds`` stops playback after that long (None:
    until the playlist ends, or forever with ``loop``).
    """

    method: str = "pixel"
    lam: float = DEFAULT_LAMBDA
    tone_tau: float = 0.5
    eye_tau: float = 0.25
    angle: float = 90.0
    eye: tuple[float, float, float] | None = None
    angle_step: float = 2.0
    monitor: int = 0
    windowed: bool = False
    size: tuple[int, int] | None = None
    vsync: bool = True
    loop: bool = False
    osc: tuple[str, int] | None = None
    stdin_fd: int | None = None
    audio: bool = True
    audio_device: str = "default"
    overlay: bool = False
    queue_size: int = 8
    tone_side: int = 32
    tone_hz: float = 5.0
    scale: str = "auto"
    max_seconds: float | None = None
    title: str = "viewcomp"
    inputs: tuple[Any, ...] = ()  # more eye sources: start(hub) -> an object with stop()


@dataclass
class PlayerStats:
    """What a run did. Times in seconds unless the name says ms."""

    presented: int = 0
    dropped: int = 0
    redrawn: int = 0
    seconds: float = 0.0
    first_present: float | None = None
    last_present: float | None = None
    render_ms: deque[float] = field(default_factory=lambda: deque(maxlen=18000))  # last 10 min
    max_present_gap_ms: float = 0.0
    max_loop_gap_ms: float = 0.0  # between main-loop iterations, after the first frames
    command_latency_ms_last: float | None = None
    command_latency_ms_max: float = 0.0
    inputs: dict[str, SourceCounts] = field(default_factory=dict)
    audio: AudioStats | None = None
    audio_device: str = ""
    files_played: int = 0

    @property
    def fps(self) -> float:
        """Presented frames per second between the first and the last presentation."""
        if self.first_present is None or self.last_present is None or self.presented < 2:
            return 0.0
        span = self.last_present - self.first_present
        return (self.presented - 1) / span if span > 0 else 0.0

    @property
    def drop_percent(self) -> float:
        """Dropped frames as a percentage of the frames due."""
        due = self.presented + self.dropped
        return 100.0 * self.dropped / due if due else 0.0

    def summary(self) -> str:
        """One line for the terminal."""
        r = np.asarray(self.render_ms) if self.render_ms else np.zeros(1)
        audio = "silent"
        if self.audio is not None:
            audio = (f"audio {self.audio_device}: {self.audio.written:.1f} s played, "
                     f"{self.audio.dropped:.2f} s dropped late")  # fmt: skip
        return (
            f"{self.presented} frames presented, {self.dropped} dropped "
            f"({self.drop_percent:.1f} %), {self.fps:.1f} frames/s, render "
            f"{float(r.mean()):.1f} ms mean / {float(np.percentile(r, 95)):.1f} ms p95, "
            f"longest gap {self.max_present_gap_ms:.0f} ms; {audio}"
        )


@dataclass(frozen=True)
class PresentedFrame:
    """Handed to ``on_frame`` after a frame is drawn and before it is presented."""

    index: int
    file_index: int
    path: Path
    time: float
    due: float
    record: FrameRecord
    planes: Planes


# ----------------------------------------------------------------------- pump messages
@dataclass(frozen=True)
class _FileStart:
    seq: int
    index: int
    path: Path
    rate: float


@dataclass(frozen=True)
class _Failure:
    exc: BaseException


_END = object()
_ENDED = object()


class _Overlay:
    """Angle, eye, fps and drops drawn with OpenCV into a texture, blitted top-left."""

    SIZE = (420, 74)

    def __init__(self, ctx: Any) -> None:
        w, h = self.SIZE
        self.tex = ctx.texture((w, h), 3, dtype="f1")
        self.fbo = ctx.framebuffer(color_attachments=[self.tex])
        self.text: tuple[str, ...] = ()
        self.updated = -1.0

    def update(self, lines: tuple[str, ...]) -> None:
        import cv2

        if lines == self.text:
            return
        w, h = self.SIZE
        img = np.zeros((h, w, 3), np.uint8)
        for i, line in enumerate(lines):
            cv2.putText(img, line, (8, 20 + 22 * i), cv2.FONT_HERSHEY_SIMPLEX, 0.5,
                        (255, 255, 255), 1, cv2.LINE_AA)  # fmt: skip
        self.tex.write(np.ascontiguousarray(img[::-1]))  # GL rows go bottom-up
        self.text = lines

    def release(self) -> None:
        self.fbo.release()
        self.tex.release()


# ----------------------------------------------------------------------- the player
class Player:
    """Plays a playlist through the compensation in a glfw window with live eye input.

    Args:
        cal: the calibration.
        playlist: video files (see :func:`expand_playlist`).
        options: :class:`PlayerOptions`.
        on_frame: called on the main thread with ``(player, PresentedFrame)`` after each
            frame is drawn, before it is presented (``read_window`` then returns it).

    ``run()`` blocks until the playlist ends (without ``loop``), Esc/q, the window is
    closed, SIGTERM/SIGINT, ``max_seconds``, or ``stop()`` from any thread; it releases
    every GL object and thread it made and returns :class:`PlayerStats`.

    Keys: Left/Right turn by ``angle_step`` (Shift: x5), Home back to the start angle,
    O the overlay, C compensation on/off (A/B), Esc/Q quit. Dragging with the left mouse
    button turns: the window's width is 180 degrees.
    """

    def __init__(
        self,
        cal: Calibration,
        playlist: Sequence[str | os.PathLike[str]],
        options: PlayerOptions | None = None,
        on_frame: Callable[[Player, PresentedFrame], None] | None = None,
    ) -> None:
        self.cal = cal
        self.options = options or PlayerOptions()
        self.playlist = expand_playlist(playlist)
        self.on_frame = on_frame
        self.hub = InputHub()
        self.stats = PlayerStats()
        self.osc_address: tuple[str, int] | None = None
        self.renderer: LiveRenderer | None = None
        self._stop = threading.Event()
        self._vq: queue.Queue[Any] = queue.Queue(maxsize=max(2, self.options.queue_size))
        self._glfw: GlfwSession | None = None
        self._egl: _EglSuspend | None = None
        self._win: Any = None
        self._ctx: Any = None
        self._overlay: _Overlay | None = None
        self._threads: list[Any] = []
        self._audio: AudioPlayer | None = None
        self._pump_thread: threading.Thread | None = None
        self._failure: BaseException | None = None
        self._next: Any = None
        self._origin = 0.0
        self._prev_end = -math.inf
        self._frame_dur = 1.0 / 30.0
        self._file = (0, self.playlist[0])
        self._render_est = 0.02
        self._last_planes: Planes | None = None
        self._drawn_eye: np.ndarray | None = None
        self._pending_inputs: list[float] = []
        self._drag: tuple[float, float] | None = None
        self._fb_size = (0, 0)
        self._viewport = (0, 0, 0, 0)
        self._show_overlay = self.options.overlay
        self._fps_now = 0.0

    # ------------------------------------------------------------------ public
    def stop(self) -> None:
        """Ask the player to stop (any thread, signal handlers included)."""
        self._stop.set()
        if self._glfw is not None:
            try:
                self._glfw.glfw.post_empty_event()
            except Exception:  # the window may be going away; the flag is enough
                pass

    def read_window(self) -> np.ndarray:
        """The grid's viewport of the window's back buffer as (H, W, 3) uint8, row 0 on top.

        Call from ``on_frame`` (before the swap) to see exactly what is about to be shown.
        """
        x, y, w, h = self._viewport
        data = self._ctx.screen.read(viewport=(x, y, w, h), components=3, alignment=1)
        return np.ascontiguousarray(np.frombuffer(data, np.uint8).reshape(h, w, 3)[::-1])

    def run(self) -> PlayerStats:
        """Play (see the class docstring); returns the statistics.

        Raises:
            PlayerError: no display or no such monitor.
            VideoError: no file of the playlist could be played.
        """
        t0 = time.monotonic()
        self._probe()  # nothing playable fails here, before any window opens
        restore = self._install_signals()
        try:
            self._open_window()
            self._start_threads()
            self._loop()
        finally:
            self._shutdown()
            restore()
        self.stats.seconds = time.monotonic() - t0
        self.stats.inputs = self.hub.snapshot()
        if self._failure is not None:
            raise self._failure
        return self.stats

    # ------------------------------------------------------------------ set-up
    def _probe(self) -> None:
        """Open files until one is readable; raise the first error if none is."""
        errors: list[VideoError] = []
        for path in self.playlist:
            try:
                with VideoReader(path, audio="none"):
                    return
            except VideoError as exc:
                if len(self.playlist) > 1:
                    log.error("will skip: %s", exc)
                errors.append(exc)
        raise errors[0]

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
        self._egl = _EglSuspend()
        self._glfw = GlfwSession(PlayerError)
        monitor = None
        if o.windowed:
            w, h = o.size or (self.cal.shape[1], self.cal.shape[0])
        else:
            monitors = glfw.get_monitors() or []
            if not 0 <= o.monitor < len(monitors):
                listing = "\n".join(f"  {m}" for m in self._glfw.monitors()) or "  (none)"
                raise PlayerError(f"no monitor {o.monitor}; the monitors are:\n{listing}\n"
                                  "fix: --monitor N with one of these, or --windowed")  # fmt: skip
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
            raise PlayerError(f"cannot create a {w}x{h} OpenGL 3.3 window "
                              f"({self._glfw.last_error}); fix: install the Debian packages "
                              "libgl1 libgl1-mesa-dri (Mesa llvmpipe is enough)")  # fmt: skip
        self._win = win
        glfw.make_context_current(win)
        glfw.swap_interval(1 if o.vsync else 0)
        if monitor is not None:
            glfw.set_input_mode(win, glfw.CURSOR, glfw.CURSOR_HIDDEN)
        self._ctx = moderngl.create_context(require=330)
        self.renderer = LiveRenderer(
            self.cal, self._ctx, method=o.method, lam=o.lam, tone_tau=o.tone_tau,
            eye_tau=o.eye_tau, angle=o.angle, eye=o.eye, async_tone=True, tone_hz=o.tone_hz,
            tone_side=o.tone_side, scale=o.scale,  # type: ignore[arg-type]
            proc_address=lambda name: int(glfw.get_proc_address(name) or 0),
        )  # fmt: skip
        self.renderer.warm_up(planes=True, present=self._viewport_needs_scaling(w, h))
        self._overlay = _Overlay(self._ctx)
        glfw.set_key_callback(win, self._on_key)
        glfw.set_mouse_button_callback(win, self._on_mouse_button)
        glfw.set_cursor_pos_callback(win, self._on_cursor)
        self._update_viewport()
        log.info("window %dx%d on %s, grid %dx%d, viewport %s", *self._fb_size,
                 "a window" if monitor is None else f"monitor {o.monitor}",
                 *self.renderer.grid, self._viewport)  # fmt: skip

    def _viewport_needs_scaling(self, w: int, h: int) -> bool:
        assert self.renderer is not None
        return (int(w), int(h)) != self.renderer.grid

    def _update_viewport(self) -> None:
        from viewcomp.rt.play.embed import fit_viewport

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
        self._pump_thread = threading.Thread(target=self._pump, name="viewcomp-pump",
                                             daemon=True)  # fmt: skip
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
            self._glfw.glfw.destroy_window(self._win)
            self._win = None
        if self._glfw is not None:
            self._glfw.close()
        if self._egl is not None:
            self._egl.restore()

    # ------------------------------------------------------------------ pump thread
    def _put(self, item: Any) -> bool:
        while not self._stop.is_set():
            try:
                self._vq.put(item, timeout=0.1)
                return True
            except queue.Full:
                continue
        return False

    def _pump(self) -> None:
        assert self.renderer is not None
        grid = self.renderer.grid
        seq = 0
        audio_mode = "frames" if self._audio is not None else "none"
        try:
            while not self._stop.is_set():
                played = 0
                for index, path in enumerate(self.playlist):
                    if self._stop.is_set():
                        return
                    try:
                        reader = VideoReader(path, fit=grid, audio=audio_mode,  # type: ignore[arg-type]
                                             queue_size=self.options.queue_size)  # fmt: skip
                    except VideoError as exc:
                        log.error("skipping: %s", exc)
                        continue
                    with reader:
                        start = reader.info.start
                        if not self._put(_FileStart(seq, index, path, float(reader.info.rate))):
                            return
                        try:
                            for item in reader:
                                if self._stop.is_set():
                                    return
                                if isinstance(item, Planes):
                                    if not self._put(item):
                                        return
                                elif self._audio is not None and item.frame is not None:
                                    t = (float(item.frame.time) - start
                                         if item.frame.time is not None else 0.0)  # fmt: skip
                                    if not self._audio.feed(seq, t, item.frame):
                                        return
                        except VideoError as exc:
                            log.error("stopped playing %s: %s", path, exc)
                    played += 1
                    seq += 1
                if not played:
                    self._put(_Failure(VideoError("none of the files in the playlist could be "
                                                  "played (see the errors above)")))  # fmt: skip
                    return
                if not self.options.loop:
                    self._put(_END)
                    return
        except BaseException as exc:  # handed to the main thread, which re-raises it
            self._put(_Failure(exc))

    # ------------------------------------------------------------------ input
    def _on_key(self, win: Any, key: int, scancode: int, action: int, mods: int) -> None:
        import glfw

        if action not in (glfw.PRESS, glfw.REPEAT):
            return
        step = self.options.angle_step * (5.0 if mods & glfw.MOD_SHIFT else 1.0)
        if key in (glfw.KEY_ESCAPE, glfw.KEY_Q):
            self.stop()
        elif key == glfw.KEY_LEFT:
            self.hub.put("key", NudgeAngle(step))
        elif key == glfw.KEY_RIGHT:
            self.hub.put("key", NudgeAngle(-step))
        elif key == glfw.KEY_HOME:
            self.hub.put("key", SetAngle(self.options.angle))
        elif key == glfw.KEY_O and action == glfw.PRESS:
            self._show_overlay = not self._show_overlay
        elif key == glfw.KEY_C and action == glfw.PRESS and self.renderer is not None:
            self.renderer.identity = not self.renderer.identity
            log.info("compensation %s", "off" if self.renderer.identity else "on")

    def _on_mouse_button(self, win: Any, button: int, action: int, mods: int) -> None:
        import glfw

        if button == glfw.MOUSE_BUTTON_LEFT:
            self._drag = glfw.get_cursor_pos(win) if action == glfw.PRESS else None

    def _on_cursor(self, win: Any, x: float, y: float) -> None:
        if self._drag is None:
            return
        width = max(self._fb_size[0], 1)
        dx = x - self._drag[0]
        self._drag = (x, y)
        if dx:
            self.hub.put("mouse", NudgeAngle(-180.0 * dx / width))

    def _apply_inputs(self) -> None:
        assert self.renderer is not None
        for item in self.hub.drain():
            self.renderer.apply(item.command)
            self.hub.applied(item)
            self._pending_inputs.append(item.at)

    # ------------------------------------------------------------------ main loop
    def _take(self) -> Any:
        while True:
            try:
                item = self._vq.get_nowait()
            except queue.Empty:
                return None
            if isinstance(item, _FileStart):
                now = time.monotonic()
                self._origin = max(self._prev_end, now + self._render_est + 0.01)
                self._frame_dur = 1.0 / item.rate if item.rate > 0 else 1.0 / 30.0
                self._file = (item.index, item.path)
                self.stats.files_played += 1
                if self._audio is not None:
                    self._audio.set_origin(item.seq, self._origin)
                continue
            if item is _END:
                return _ENDED
            if isinstance(item, _Failure):
                self._failure = item.exc
                return _ENDED
            return item

    def _idle(self, seconds: float) -> None:
        if seconds > 0.0005:
            self._glfw.glfw.wait_events_timeout(seconds)  # type: ignore[union-attr]
        else:
            self._glfw.glfw.poll_events()  # type: ignore[union-attr]

    def _loop(self) -> None:
        glfw = self._glfw.glfw  # type: ignore[union-attr]
        renderer = self.renderer
        assert renderer is not None
        o = self.options
        deadline = None if o.max_seconds is None else time.monotonic() + o.max_seconds
        last_iter = time.monotonic()
        while not self._stop.is_set():
            glfw.poll_events()
            now = time.monotonic()
            if self.stats.presented > 1:  # once playing: start-up (shader compile) excluded
                gap = 1e3 * (now - last_iter)
                self.stats.max_loop_gap_ms = max(self.stats.max_loop_gap_ms, gap)
            last_iter = now
            if glfw.window_should_close(self._win) or (deadline is not None and now > deadline):
                break
            self._apply_inputs()
            if self._next is None:
                self._next = self._take()
            if self._next is _ENDED:  # let the last frame stay up for its slot
                while not self._stop.is_set() and time.monotonic() < self._prev_end:
                    self._idle(min(self._prev_end - time.monotonic(), 0.01))
                break
            item = self._next
            if item is None:  # the decoder is behind: keep the eye live on the last frame
                stale = now - (self.stats.last_present or now) > 2.0 * self._frame_dur
                if (
                    stale
                    and self._last_planes is not None
                    and not np.array_equal(renderer.eye_state.update(now), self._drawn_eye)
                ):
                    self._present(self._last_planes, now, redraw=True)
                else:
                    self._idle(0.003)
                continue
            due = self._origin + item.time
            if now > due + self._frame_dur:  # its whole slot has passed
                self.stats.dropped += 1
                self._prev_end = due + self._frame_dur
                self._next = None
                continue
            lead = due - now - self._render_est
            if lead > 0.002:
                self._idle(min(lead - 0.001, 0.010))
                continue
            self._present(item, due)
            self._prev_end = due + self._frame_dur
            self._next = None

    def _overlay_lines(self) -> tuple[str, ...]:
        assert self.renderer is not None
        eye = self.renderer.eye
        angle, _d, _h = eye_to_polar(eye)
        s = self.stats
        idx, path = self._file
        return (
            f"angle {angle:6.1f} deg  eye ({eye[0]:+.3f}, {eye[1]:+.3f}, {eye[2]:+.3f}) m",
            f"{self._fps_now:5.1f} fps  dropped {s.dropped} ({s.drop_percent:.1f} %)"
            + ("  COMPENSATION OFF" if self.renderer.identity else ""),
            f"file {idx + 1}/{len(self.playlist)}: {path.name[:40]}",
        )

    def _present(self, planes: Planes, due: float, redraw: bool = False) -> None:
        glfw = self._glfw.glfw  # type: ignore[union-attr]
        renderer = self.renderer
        assert renderer is not None and self._overlay is not None
        self._update_viewport()
        t0 = time.monotonic()
        record = renderer.prepare(planes, now=t0)
        renderer.draw(self._ctx.screen, self._viewport, size=self._fb_size)
        if self._show_overlay:
            if t0 - self._overlay.updated > 0.25:
                self._overlay.update(self._overlay_lines())
                self._overlay.updated = t0
            ow, oh = _Overlay.SIZE
            fw, fh = self._fb_size
            renderer.blit(self._overlay.fbo, (0, 0, ow, oh), self._ctx.screen,
                          (8, max(fh - oh - 8, 0), min(ow, fw), min(oh, fh)))  # fmt: skip
        renderer.finish()
        cost = time.monotonic() - t0
        self._render_est = 0.8 * self._render_est + 0.2 * cost
        self.stats.render_ms.append(1e3 * cost)
        if self.on_frame is not None:
            idx, path = self._file
            self.on_frame(self, PresentedFrame(self.stats.presented, idx, path, planes.time,
                                               due, record, planes))  # fmt: skip
        while True:
            wait = due - time.monotonic()
            if wait <= 0:
                break
            self._idle(min(wait, 0.005)) if wait > 0.002 else time.sleep(wait)
        glfw.swap_buffers(self._win)
        t = time.monotonic()
        s = self.stats
        if s.last_present is not None:
            s.max_present_gap_ms = max(s.max_present_gap_ms, 1e3 * (t - s.last_present))
            if t > s.last_present:
                self._fps_now = 0.9 * self._fps_now + 0.1 / (t - s.last_present)
        if s.first_present is None:
            s.first_present = t
        s.last_present = t
        if redraw:
            s.redrawn += 1
        else:
            s.presented += 1
        if self._pending_inputs:
            lat = 1e3 * (t - min(self._pending_inputs))
            s.command_latency_ms_last = 1e3 * (t - max(self._pending_inputs))
            s.command_latency_ms_max = max(s.command_latency_ms_max, lat)
            self._pending_inputs.clear()
        self._last_planes = planes
        self._drawn_eye = record.eye
