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

Show control (pause, resume, seek, next, previous) is a *jump*
(:mod:`viewcomp.rt.play.show_control`). A still image (an image file) stays up for
``still_seconds``.

The player is one class made of one module per concern: the playlist pump
(:mod:`~viewcomp.rt.play.playlist`), show control and keys
(:mod:`~viewcomp.rt.play.show_control`), status and statistics
(:mod:`~viewcomp.rt.play.player_status`), the window and GL life cycle
(:mod:`~viewcomp.rt.play.window`); this module holds the options, the state and the main
loop that schedules and presents the frames.
"""

from __future__ import annotations

import logging
import math
import os
import queue
import threading
import time
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from viewcomp.calib.errors import PlayerError
from viewcomp.rt.media.frames import Planes
from viewcomp.rt.media.video import VideoError, VideoReader
from viewcomp.rt.play.display_watch import DisplayWatch
from viewcomp.rt.play.live import InputHub
from viewcomp.rt.play.overlay import Overlay
from viewcomp.rt.play.player_options import PlayerOptions
from viewcomp.rt.play.player_status import (
    DROP_LOG_PERIOD,
    PlayerStats,
    PlayerStatus,
    PresentedFrame,
    StatusReport,
    _Shown,
)
from viewcomp.rt.play.playlist import (
    _ENDED,
    IMAGE_SUFFIXES,
    VIDEO_SUFFIXES,
    PlaylistPump,
    _End,
    _Failure,
    _FileStart,
    expand_playlist,
    is_still,
)
from viewcomp.rt.play.sdnotify import Notifier
from viewcomp.rt.play.show_control import SEEK_STEP, SHOW_TYPES, ShowControl
from viewcomp.rt.play.window import WindowLifecycle, list_monitors

if TYPE_CHECKING:
    from viewcomp.calib.fit.calibrate import Calibration
    from viewcomp.rt.play.embed import LiveRenderer

__all__ = [
    "DROP_LOG_PERIOD", "IMAGE_SUFFIXES", "SEEK_STEP", "SHOW_TYPES", "VIDEO_SUFFIXES", "Player",
    "PlayerError", "PlayerOptions", "PlayerStats", "PlayerStatus", "PresentedFrame",
    "expand_playlist", "is_still", "list_monitors",
]  # fmt: skip

log = logging.getLogger(__name__)

REDRAW_GAP = 1.0 / 30.0  # seconds: between redraws of a held picture for a moving eye


class Player(PlaylistPump, ShowControl, StatusReport, WindowLifecycle, DisplayWatch):
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
        self.renderer: LiveRenderer | None = None
        self._stop = threading.Event()
        self._init_pump()
        self._init_show_control()
        self._init_status()
        self._init_window()
        self._init_display_watch()
        # the schedule (main thread): the frame waiting to be shown and the file it is from
        self._failure: BaseException | None = None
        self._notify = Notifier()  # systemd's readiness and watchdog; a no-op outside it
        self._next: Any = None
        self._origin: float | None = None  # set when the file's first frame is scheduled
        self._floor = -math.inf  # a file's first frame is due no earlier than this
        self._cur_gen = 0  # the jump the queued items belong to (main thread)
        self._seq = 0
        self._still = False
        self._shown: _Shown | None = None
        self._drawn_key: tuple[Any, ...] | None = None
        self._prev_end = -math.inf
        self._frame_dur = 1.0 / 30.0
        self._file = (0, self.playlist[0])
        self._render_est = 0.02
        self._last_planes: Planes | None = None
        self._drawn_eye: np.ndarray | None = None

    # ------------------------------------------------------------------ public
    def stop(self) -> None:
        """Ask the player to stop (any thread, signal handlers included)."""
        self._stop.set()
        if self._glfw is not None:
            try:
                self._glfw.glfw.post_empty_event()
            except Exception:  # the window may be going away; the flag is enough
                pass

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
            self._notify.stopping()
            self._shutdown()
            self._notify.close()
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

    def _state_key(self, now: float) -> tuple[Any, ...]:
        assert self.renderer is not None
        eye = self.renderer.eye_state.update(now)
        return (tuple(float(v) for v in eye), self._blackout, self.renderer.identity)

    def _redraw(self, now: float) -> bool:
        """Draw the frame on screen again when the eye, blackout or A/B state changed since
        (a held picture: paused, a still, a decoder behind); True if it drew."""
        if self._last_planes is None or self._shown is None or self._display_lost:
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
            self._reattach_display()
            now = time.monotonic()
            if self.stats.presented > 1:  # once playing: start-up (shader compile) excluded
                gap = 1e3 * (now - last_iter)
                self.stats.max_loop_gap_ms = max(self.stats.max_loop_gap_ms, gap)
            last_iter = now
            self._notify.watchdog(now)  # a hung loop stops pinging: systemd restarts it
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

    def _present(self, planes: Planes, due: float, redraw: bool = False) -> None:
        if self._display_lost:
            self._unshown(planes, redraw)
            return
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
            ow, oh = Overlay.SIZE
            fw, fh = self._fb_size
            renderer.blit(
                self._overlay.fbo,
                (0, 0, ow, oh),
                self._ctx.screen,
                (8, max(fh - oh - 8, 0), min(ow, fw), min(oh, fh)),
            )
        renderer.finish()
        cost = time.monotonic() - t0
        self._render_est = 0.8 * self._render_est + 0.2 * cost
        self.stats.render_ms.append(1e3 * cost)
        idx, path = self._file
        still = self._still
        if redraw and planes is self._last_planes and self._shown is not None:
            idx, path, still = self._shown.index, self._shown.path, self._shown.still
        if self.on_frame is not None:
            self.on_frame(
                self,
                PresentedFrame(self.stats.presented, idx, path, planes.time, due, record, planes),
            )
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
            self._notify.ready(f"playing {path.name}")  # the projector shows the picture
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
