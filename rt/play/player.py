"""`viewcomp play`: fullscreen playback with a live viewing angle (glfw window, GL 3.3).

Threads and who owns what:

- main thread: the glfw window, the GL context and every GL object (through
  :class:`~viewcomp.rt.play.embed.LiveRenderer`), input callbacks, the clock, presentation;
- ``viewcomp-pump``: walks the playlist, opens each file with
  :class:`~viewcomp.rt.media.video.VideoReader` (its own decode thread and bounded queue, frames
  fitted to the projector grid) and forwards frames to a bounded queue and audio to the
  :class:`~viewcomp.rt.media.audio.AudioPlayer`;
- ``viewcomp-tone``: the tone map (and the paper method's model) for the newest frame;
- ``viewcomp-osc`` / ``viewcomp-stdin``: live input, the eye and the show control
  (:mod:`viewcomp.rt.play.live`), applied by the main thread;
- ``viewcomp-audio``: writes audio to the device, on the wall clock.

Timing: the wall clock (``time.monotonic``) leads. File k's frame at time t is due at
``origin_k + t``; origin_k is where file k-1 ended (or now, if that has passed). A frame is
drawn when it is due within the render time (running estimate), presented (buffer swap) at
its due time, and dropped unrendered when its slot (due .. due + 1/rate) has passed: late
frames never accumulate and the picture never drifts. With vsync the swap waits for the
display's next refresh. Audio chunks are due on the same clock (see ``rt/audio.py``).

Show control (pause, resume, seek, next, previous) is a *jump*: the main thread numbers it
(a generation) and hands (file, position) to the pump, which reopens that file there; the
main thread drops what the pump had queued for older generations. A pause is a jump to the
frame on screen that is held until resume, so the audio of the old position is dropped and
resumes in step. A still image (an image file) stays up for ``still_seconds``.

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
import socket
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from viewcomp.calib.comp.tonemap import DEFAULT_LAMBDA
from viewcomp.calib.world.audience import Audience
from viewcomp.rt.gl.context import core_profile_hints, libegl
from viewcomp.rt.media.audio import AudioPlayer, AudioStats, open_alsa
from viewcomp.rt.media.frames import Planes
from viewcomp.rt.media.video import VideoError, VideoReader
from viewcomp.rt.play.glfw_session import GlfwSession, MonitorInfo
from viewcomp.rt.play.glfw_session import list_monitors as glfw_monitors
from viewcomp.rt.play.live import (
    NORM_RANGE,
    STATUS_ADDRESS,
    Blackout,
    InputHub,
    LineReader,
    Next,
    NudgeAngle,
    OscListener,
    Pause,
    Previous,
    Resume,
    Seek,
    SetAngle,
    SourceCounts,
    Status,
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
IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp"}
SHOW_TYPES = (Pause, Resume, Seek, Next, Previous, Blackout, Status)
DROP_LOG_PERIOD = 5.0  # seconds: dropped frames are logged at most this often
REDRAW_GAP = 1.0 / 30.0  # seconds: between redraws of a held picture for a moving eye
SEEK_STEP = 10.0  # seconds per [ or ] key


class PlayerError(RuntimeError):
    """Playback cannot start (no display, no such monitor, empty playlist); says why."""


# ----------------------------------------------------------------------- playlist
def expand_playlist(paths: Sequence[str | os.PathLike[str]]) -> list[Path]:
    """Files as given, folders expanded to their video and image files (by extension, sorted
    by name).

    Raises:
        PlayerError: a path that does not exist, or nothing to play.
    """
    out: list[Path] = []
    for raw in paths:
        p = Path(raw)
        if p.is_dir():
            found = sorted(
                (q for q in p.iterdir() if q.is_file() and not q.name.startswith(".")
                 and q.suffix.lower() in VIDEO_SUFFIXES | IMAGE_SUFFIXES),
                key=lambda q: q.name.lower(),
            )  # fmt: skip
            if not found:
                raise PlayerError(
                    f"folder {p} has no video or image files "
                    f"({', '.join(sorted(VIDEO_SUFFIXES | IMAGE_SUFFIXES))})"
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
    until the playlist ends, or forever with ``loop``). ``still_seconds``: how long an image
    file stays up; ``norm_range``: the angles (degrees) ``/viewcomp/angle/norm`` 0 and 1 mean;
    ``osc_feedback`` (host, port): where the status is pushed every ``feedback_every`` s.
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
    still_seconds: float = 10.0
    norm_range: tuple[float, float] = NORM_RANGE
    osc_feedback: tuple[str, int] | None = None
    feedback_every: float = 1.0
    inputs: tuple[Any, ...] = ()  # more eye sources: start(hub) -> an object with stop()
    audience: Audience | None = None  # several viewers at once from the start (pixel method)


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
    stills: int = 0  # still images shown (not counted in presented)

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
        parts = []
        if self.presented or not self.stills:
            rate = "" if self.stills else f", {self.fps:.1f} frames/s"
            parts.append(f"{self.presented} video frames presented, {self.dropped} dropped "
                         f"({self.drop_percent:.1f} %){rate}")  # fmt: skip
        if self.stills:
            parts.append(f"{self.stills} still image{'s' if self.stills != 1 else ''} shown")
        return (
            f"{', '.join(parts)}, render {float(r.mean()):.1f} ms mean / "
            f"{float(np.percentile(r, 95)):.1f} ms p95, longest gap "
            f"{self.max_present_gap_ms:.0f} ms; {audio}"
        )


@dataclass(frozen=True)
class PlayerStatus:
    """What the player shows now (``/viewcomp/status``, stdin ``status``).

    ``file`` the path of the file on screen, ``position`` the time of the frame on screen
    (seconds from the file's first frame), ``angle`` degrees and ``eye`` metres of the eye
    the frame on screen was drawn for, ``fps`` presented frames per second (smoothed),
    ``dropped`` late frames dropped so far, ``blackout`` whether the screen is black.
    """

    file: str
    position: float
    paused: bool
    angle: float
    eye: tuple[float, float, float]
    fps: float
    dropped: int
    blackout: bool

    def osc(self) -> bytes:
        """``/viewcomp/status s f i f f f f f i i`` (the fields in order)."""
        from pythonosc.osc_message_builder import OscMessageBuilder

        b = OscMessageBuilder(STATUS_ADDRESS)
        b.add_arg(self.file, "s")
        b.add_arg(float(self.position), "f")
        b.add_arg(int(self.paused), "i")
        b.add_arg(float(self.angle), "f")
        for v in self.eye:
            b.add_arg(float(v), "f")
        b.add_arg(float(self.fps), "f")
        b.add_arg(int(self.dropped), "i")
        b.add_arg(int(self.blackout), "i")
        return b.build().dgram

    def line(self) -> str:
        """One line for stdout: ``status file=... position=12.345 paused=0 ...``."""
        x, y, z = self.eye
        return (f"status file={self.file} position={self.position:.3f} paused={int(self.paused)} "
                f"angle={self.angle:.2f} eye={x:.4f},{y:.4f},{z:.4f} fps={self.fps:.1f} "
                f"dropped={self.dropped} blackout={int(self.blackout)}")  # fmt: skip


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
    gen: int
    index: int
    path: Path
    rate: float
    still: bool
    jumped: bool


@dataclass(frozen=True)
class _End:
    gen: int


@dataclass(frozen=True)
class _Failure:
    exc: BaseException


@dataclass(frozen=True)
class _Shown:
    """The frame on screen: file index and path, its time, whether a still, when shown."""

    index: int
    path: Path
    time: float
    still: bool
    at: float
    eye: tuple[float, float, float]
    blackout: bool


_ENDED = object()


def is_still(path: Path, frames: int | None) -> bool:
    """An image file (by extension), or a video of a single frame."""
    return path.suffix.lower() in IMAGE_SUFFIXES or frames == 1


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
    Space pause/resume, ``]``/``[`` seek 10 s on/back, N or Page Down next file, P or Page
    Up previous, B blackout on/off, S status to stdout, O the overlay, C compensation on/off
    (A/B), Esc/Q quit. Dragging with the left mouse button turns: the window's width is 180
    degrees.
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
        self._sources = list(playlist)
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
        self._origin: float | None = None  # set when the file's first frame is scheduled
        self._floor = -math.inf  # a file's first frame is due no earlier than this
        self._gen = 0  # jumps requested (main thread)
        self._cur_gen = 0  # the jump the queued items belong to (main thread)
        self._jump: tuple[int, int, float] | None = None  # (gen, index, seconds) for the pump
        self._jump_lock = threading.Lock()
        self._seq = 0
        self._still = False
        self._paused = False
        self._show_next = False  # paused: show the next frame (after a seek, next, previous)
        self._blackout = False
        self._shown: _Shown | None = None
        self._drawn_key: tuple[Any, ...] | None = None
        self._drops_unlogged = 0
        self._drop_logged_at = -math.inf
        self._feedback_at = -math.inf
        self._osc: OscListener | None = None
        self._sock: socket.socket | None = None
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

    def status(self) -> PlayerStatus:
        """What is on screen now (main thread; see :class:`PlayerStatus`)."""
        shown = self._shown
        if shown is None:
            eye = tuple(float(v) for v in self.renderer.eye) if self.renderer else (0.0,) * 3
            file, position = str(self._file[1]), 0.0
        else:
            eye, file, position = shown.eye, str(shown.path), shown.time
        return PlayerStatus(
            file=file, position=position, paused=self._paused,
            angle=eye_to_polar(np.asarray(eye))[0], eye=eye,  # type: ignore[arg-type]
            fps=self._fps_now, dropped=self.stats.dropped,
            blackout=self._blackout if shown is None else shown.blackout,
        )  # fmt: skip

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
            eye_tau=o.eye_tau, angle=o.angle, eye=o.eye, audience=o.audience, async_tone=True,
            tone_hz=o.tone_hz,
            tone_side=o.tone_side, scale=o.scale,  # type: ignore[arg-type]
            proc_address=lambda name: int(glfw.get_proc_address(name) or 0),
        )  # fmt: skip
        self.renderer.eye_state.norm_range = o.norm_range
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
            self._glfw.glfw.destroy_window(self._win)
            self._win = None
        if self._glfw is not None:
            self._glfw.close()
        if self._egl is not None:
            self._egl.restore()

    # ------------------------------------------------------------------ pump thread
    def _put(self, item: Any) -> bool:
        """Queue an item for the main thread; False when stopping or a jump is pending."""
        while not self._stop.is_set():
            if self._jump is not None:
                return False
            try:
                self._vq.put(item, timeout=0.1)
                return True
            except queue.Full:
                continue
        return False

    def _take_jump(self) -> tuple[int, int, float] | None:
        with self._jump_lock:
            jump, self._jump = self._jump, None
        return jump

    def _refresh_playlist(self) -> None:
        """Re-read the folders of the playlist: files added since are played too."""
        if not any(Path(p).is_dir() for p in self._sources):
            return
        try:
            new = expand_playlist(self._sources)
        except PlayerError:  # a folder emptied or gone: play on with what was there
            return
        added = [p.name for p in new if p not in self.playlist]
        if added:
            log.info("playlist: %d new file%s: %s", len(added), "s" if len(added) > 1 else "",
                     ", ".join(added[:5]) + (" ..." if len(added) > 5 else ""))  # fmt: skip
        self.playlist = new

    def _pump(self) -> None:
        assert self.renderer is not None
        grid = self.renderer.grid
        seq, gen, index, start, jumped = 0, 0, 0, 0.0, False
        bad = 0  # unreadable files in a row
        audio_mode = "frames" if self._audio is not None else "none"
        try:
            while not self._stop.is_set():
                playlist = self.playlist
                if index < 0:
                    index = len(playlist) - 1 if self.options.loop else 0
                if index >= len(playlist):
                    if self.options.loop:
                        index = 0
                    else:  # the end: wait for a jump back (previous, seek) or the stop
                        self._put(_End(gen))
                        jump = None
                        while jump is None and not self._stop.wait(0.02):
                            jump = self._take_jump()
                        if jump is None:
                            return
                        gen, index, start = jump
                        jumped = True
                        continue
                path = playlist[index]
                try:
                    reader = VideoReader(path, fit=grid, audio=audio_mode,  # type: ignore[arg-type]
                                         queue_size=self.options.queue_size,
                                         start_at=start)  # fmt: skip
                except VideoError as exc:
                    log.error("skipping: %s", exc)
                    bad += 1
                    if bad >= len(playlist):
                        self._put(_Failure(VideoError("none of the files in the playlist "
                                                      "could be played (see the errors "
                                                      "above)")))  # fmt: skip
                        return
                    index, start = index + 1, 0.0
                    continue
                bad = 0
                jump = None
                with reader:
                    start0 = reader.info.start
                    still = is_still(path, reader.info.frames)
                    if self._put(_FileStart(seq, gen, index, path, float(reader.info.rate),
                                            still, jumped)):  # fmt: skip
                        try:
                            for item in reader:
                                if self._stop.is_set():
                                    return
                                if self._jump is not None:
                                    break
                                if isinstance(item, Planes):
                                    if not self._put(item):
                                        break
                                elif self._audio is not None and item.frame is not None:
                                    t = (float(item.frame.time) - start0
                                         if item.frame.time is not None else 0.0)  # fmt: skip
                                    if not self._audio.feed(seq, t, item.frame):
                                        return
                        except VideoError as exc:
                            log.error("stopped playing %s: %s", path, exc)
                if self._stop.is_set():
                    return
                seq += 1
                jump = self._take_jump()
                if jump is not None:
                    if self._audio is not None:
                        self._audio.cancel(seq - 1)
                    gen, index, start = jump
                    jumped = True
                    continue
                self._refresh_playlist()
                if path in self.playlist:
                    index = self.playlist.index(path)
                index, start, jumped = index + 1, 0.0, False
        except BaseException as exc:  # handed to the main thread, which re-raises it
            while not self._stop.is_set():
                self._take_jump()
                if self._put(_Failure(exc)):
                    return

    # ------------------------------------------------------------------ input
    def _on_key(self, win: Any, key: int, scancode: int, action: int, mods: int) -> None:
        import glfw

        if action not in (glfw.PRESS, glfw.REPEAT):
            return
        press = action == glfw.PRESS
        step = self.options.angle_step * (5.0 if mods & glfw.MOD_SHIFT else 1.0)
        if key in (glfw.KEY_ESCAPE, glfw.KEY_Q):
            self.stop()
        elif key == glfw.KEY_LEFT:
            self.hub.put("key", NudgeAngle(step))
        elif key == glfw.KEY_RIGHT:
            self.hub.put("key", NudgeAngle(-step))
        elif key == glfw.KEY_HOME:
            self.hub.put("key", SetAngle(self.options.angle))
        elif key == glfw.KEY_SPACE and press:
            self.hub.put("key", Resume() if self._paused else Pause())
        elif key == glfw.KEY_RIGHT_BRACKET:
            self.hub.put("key", Seek(SEEK_STEP, relative=True))
        elif key == glfw.KEY_LEFT_BRACKET:
            self.hub.put("key", Seek(-SEEK_STEP, relative=True))
        elif key in (glfw.KEY_N, glfw.KEY_PAGE_DOWN) and press:
            self.hub.put("key", Next())
        elif key in (glfw.KEY_P, glfw.KEY_PAGE_UP) and press:
            self.hub.put("key", Previous())
        elif key == glfw.KEY_B and press:
            self.hub.put("key", Blackout(not self._blackout))
        elif key == glfw.KEY_S and press:
            self.hub.put("key", Status())
        elif key == glfw.KEY_O and press:
            self._show_overlay = not self._show_overlay
        elif key == glfw.KEY_C and press and self.renderer is not None:
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
            if isinstance(item.command, SHOW_TYPES):
                self._show_control(item.command)
            else:
                self.renderer.apply(item.command)
            self.hub.applied(item)
            self._pending_inputs.append(item.at)

    # ------------------------------------------------------------------ show control
    def _request_jump(self, index: int, seconds: float) -> None:
        """Have the pump reopen playlist file ``index`` at ``seconds``; drop what is queued."""
        with self._jump_lock:
            self._gen += 1
            self._jump = (self._gen, index, max(seconds, 0.0))
        self._next = None
        self._origin = None
        self._floor = -math.inf
        if self._paused:
            self._show_next = True

    def _show_control(self, cmd: Any) -> None:
        shown = self._shown
        index = shown.index if shown is not None else self._file[0]
        position = shown.time if shown is not None else 0.0
        if isinstance(cmd, Pause):
            if not self._paused:
                self._request_jump(index, position)
                self._paused = True
                self._show_next = shown is None  # else the frame on screen is the one held
                log.info("paused at %.2f s of %s", position, self._file[1].name)
        elif isinstance(cmd, Resume):
            if self._paused:
                self._paused = False
                self._show_next = False
                self._origin = None
                self._floor = -math.inf
                log.info("resumed")
        elif isinstance(cmd, Seek):
            target = position + cmd.seconds if cmd.relative else cmd.seconds
            self._request_jump(index, target)
            log.info("seek to %.2f s", max(target, 0.0))
        elif isinstance(cmd, Next):
            self._request_jump(index + 1, 0.0)
        elif isinstance(cmd, Previous):
            self._request_jump(index - 1, 0.0)
        elif isinstance(cmd, Blackout):
            if cmd.on != self._blackout:
                self._blackout = cmd.on
                log.info("blackout %s", "on" if cmd.on else "off")
        elif isinstance(cmd, Status):
            st = self.status()
            if cmd.reply_to is None:
                print(st.line(), flush=True)
            else:
                self._send(st.osc(), cmd.reply_to)

    def _send(self, data: bytes, address: tuple[str, int]) -> None:
        """A datagram to ``address``, from the OSC socket when listening (so replies come
        from the port the controller sends to)."""
        if self._osc is not None:
            self._osc.send(data, address)
            return
        if self._sock is None:
            family = socket.AF_INET6 if ":" in address[0] else socket.AF_INET
            self._sock = socket.socket(family, socket.SOCK_DGRAM)
        try:
            self._sock.sendto(data, address)
        except OSError as exc:
            log.warning("osc feedback: cannot send to %s:%d: %s", *address, exc)

    def _feedback(self, now: float) -> None:
        o = self.options
        if o.osc_feedback is None or now - self._feedback_at < o.feedback_every:
            return
        self._feedback_at = now
        self._send(self.status().osc(), o.osc_feedback)

    def _dropped(self, now: float, due: float) -> None:
        self.stats.dropped += 1
        self._drops_unlogged += 1
        if now - self._drop_logged_at >= DROP_LOG_PERIOD:
            log.warning("dropped %d late frame%s (%s at %.2f s; %d in all)",
                        self._drops_unlogged, "s" if self._drops_unlogged > 1 else "",
                        self._file[1].name, due - (self._origin or 0.0),
                        self.stats.dropped)  # fmt: skip
            self._drops_unlogged = 0
            self._drop_logged_at = now

    # ------------------------------------------------------------------ main loop
    def _take(self) -> Any:
        while True:
            try:
                item = self._vq.get_nowait()
            except queue.Empty:
                return None
            if isinstance(item, _Failure):
                self._failure = item.exc
                return _ENDED
            if isinstance(item, _FileStart):
                self._cur_gen = item.gen
                if item.gen < self._gen:
                    continue
                self._seq = item.seq
                self._still = item.still
                if item.still:
                    self._frame_dur = max(self.options.still_seconds, 1e-3)
                else:
                    self._frame_dur = 1.0 / item.rate if item.rate > 0 else 1.0 / 30.0
                self._file = (item.index, item.path)
                self._origin = None
                self._floor = -math.inf if item.jumped else self._prev_end
                self.stats.files_played += 1
                continue
            if isinstance(item, _End):
                if item.gen < self._gen:
                    continue
                return _ENDED
            if self._cur_gen < self._gen:  # queued before a jump
                continue
            return item

    def _idle(self, seconds: float) -> None:
        if seconds > 0.0005:
            self._glfw.glfw.wait_events_timeout(seconds)  # type: ignore[union-attr]
        else:
            self._glfw.glfw.poll_events()  # type: ignore[union-attr]

    def _state_key(self, now: float) -> tuple[Any, ...]:
        assert self.renderer is not None
        eye = self.renderer.eye_state.update(now)
        return (tuple(float(v) for v in eye), self._blackout, self.renderer.identity)

    def _redraw(self, now: float) -> bool:
        """Draw the frame on screen again when the eye, blackout or A/B state changed since
        (a held picture: paused, a still, a decoder behind); True if it drew."""
        if self._last_planes is None or self._shown is None:
            return False
        key = self._state_key(now)
        if key == self._drawn_key:
            return False
        switched = self._drawn_key is None or key[1:] != self._drawn_key[1:]
        if not switched and now - (self.stats.last_present or now) < REDRAW_GAP:
            return False
        self._present(self._last_planes, now, redraw=True)
        return True

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
            self._feedback(now)
            if self._next is None:
                self._next = self._take()
            if self._next is _ENDED:  # let the last frame stay up for its slot
                while not self._stop.is_set() and time.monotonic() < self._prev_end:
                    self._apply_inputs()
                    if self._next is not _ENDED:  # a jump back (previous, seek)
                        break
                    self._redraw(time.monotonic())
                    self._idle(min(self._prev_end - time.monotonic(), 0.01))
                if self._next is not _ENDED:
                    continue
                break
            item = self._next
            if self._paused:
                if item is not None and self._show_next:
                    self._show_next = False
                    self._next = None
                    self._present(item, now, redraw=True)
                elif not self._redraw(now):
                    self._idle(0.005)
                continue
            if item is None:  # the decoder is behind: keep the eye live on the last frame
                if not self._redraw(now):
                    self._idle(0.003)
                continue
            if self._origin is None:
                self._origin = max(self._floor, now + self._render_est + 0.01) - item.time
                if self._audio is not None:
                    self._audio.set_origin(self._seq, self._origin)
            due = self._origin + item.time
            if now > due + self._frame_dur:  # its whole slot has passed
                self._dropped(now, due)
                self._prev_end = due + self._frame_dur
                self._next = None
                continue
            lead = due - now - self._render_est
            if lead > 0.002:
                if lead < 2.0 * self._render_est + 0.005 or not self._redraw(now):
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
        state = " PAUSED" if self._paused else ""
        aud = self.renderer.audience
        who = f"  ({len(aud)} viewers: their mean)" if aud is not None else ""
        return (
            f"angle {angle:6.1f} deg  eye ({eye[0]:+.3f}, {eye[1]:+.3f}, {eye[2]:+.3f}) m{who}",
            f"{self._fps_now:5.1f} fps  dropped {s.dropped} ({s.drop_percent:.1f} %)"
            + ("  COMPENSATION OFF" if self.renderer.identity else ""),
            f"file {idx + 1}/{len(self.playlist)}: {path.name[:40]}{state}",
        )

    def _present(self, planes: Planes, due: float, redraw: bool = False) -> None:
        glfw = self._glfw.glfw  # type: ignore[union-attr]
        renderer = self.renderer
        assert renderer is not None and self._overlay is not None
        self._update_viewport()
        t0 = time.monotonic()
        record = renderer.prepare(planes, now=t0)
        if self._blackout:
            self._ctx.screen.use()
            self._ctx.screen.clear(0.0, 0.0, 0.0, 1.0)
        else:
            renderer.draw(self._ctx.screen, self._viewport, size=self._fb_size, clear=True)
        if self._show_overlay and not self._blackout:
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
        idx, path = self._file
        still = self._still
        if redraw and planes is self._last_planes and self._shown is not None:
            idx, path, still = self._shown.index, self._shown.path, self._shown.still
        if self.on_frame is not None:
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
            if t > s.last_present and not redraw and not still:
                self._fps_now = 0.9 * self._fps_now + 0.1 / (t - s.last_present)
        if s.first_present is None:
            s.first_present = t
        s.last_present = t
        if redraw:
            s.redrawn += 1
        elif still:
            s.stills += 1
        else:
            s.presented += 1
        if self._pending_inputs:
            lat = 1e3 * (t - min(self._pending_inputs))
            s.command_latency_ms_last = 1e3 * (t - max(self._pending_inputs))
            s.command_latency_ms_max = max(s.command_latency_ms_max, lat)
            self._pending_inputs.clear()
        self._last_planes = planes
        self._drawn_eye = record.eye
        eye = tuple(float(v) for v in record.eye)
        self._drawn_key = (eye, self._blackout, renderer.identity)
        self._shown = _Shown(idx, path, planes.time, still, t, eye, self._blackout)  # type: ignore[arg-type]
