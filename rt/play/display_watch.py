"""The projector's display going away and coming back while `viewcomp play` runs.

A projector switched off, an HDMI cable pulled, a KVM or a matrix switcher changing input:
the X server's RandR reports the output gone (glfw's monitor callback, DISCONNECTED), and
glfw turns a fullscreen window on that monitor into a plain window. The player does not
stop or restart: while the display is gone it keeps its schedule (frames come due and are
counted as unshown, audio goes on, show control and live input are applied) and draws
nothing; when a monitor of that name (or, failing that, the ``--monitor`` index) is back, the
window goes fullscreen on it again and playback is shown from where the schedule is. Each
loss and each return is logged once, and told to systemd (``STATUS=``).

Only a fullscreen player watches: a ``--windowed`` one has no monitor to lose.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from viewcomp.rt.play.player_status import _Shown

if TYPE_CHECKING:
    from viewcomp.rt.media.frames import Planes
    from viewcomp.rt.play.embed import LiveRenderer
    from viewcomp.rt.play.glfw_session import GlfwSession
    from viewcomp.rt.play.player_options import PlayerOptions
    from viewcomp.rt.play.player_status import PlayerStats
    from viewcomp.rt.play.sdnotify import Notifier

log = logging.getLogger(__name__)


def _name(glfw: Any, monitor: Any) -> str:
    raw = glfw.get_monitor_name(monitor)
    return raw.decode(errors="replace") if isinstance(raw, bytes) else str(raw)


class DisplayWatch:
    """Loss and return of the fullscreen window's monitor (a mixin of
    :class:`~viewcomp.rt.play.player.Player`; main thread: glfw calls the monitor callback from
    ``poll_events``)."""

    options: PlayerOptions
    stats: PlayerStats
    _glfw: GlfwSession | None
    _win: Any
    _notify: Notifier
    _display_name: str | None  # the monitor the window is fullscreen on; None: windowed
    _display_lost: bool
    _display_back: bool  # a monitor came back: go fullscreen on it at the next loop turn
    # the player's schedule state that an unshown frame updates
    renderer: LiveRenderer | None
    _file: tuple[int, Path]
    _still: bool
    _blackout: bool
    _last_planes: Planes | None
    _drawn_key: tuple[Any, ...] | None
    _shown: _Shown | None
    _pending_inputs: list[float]

    def _init_display_watch(self) -> None:
        self._display_name = None
        self._display_lost = False
        self._display_back = False

    def _watch_display(self, monitor: Any) -> None:
        """Start watching ``monitor`` (the glfw monitor the window was made fullscreen on)."""
        glfw = self._glfw.glfw  # type: ignore[union-attr]
        self._display_name = _name(glfw, monitor)
        glfw.set_monitor_callback(self._on_monitor)

    def _unwatch_display(self) -> None:
        if self._display_name is not None and self._glfw is not None:
            self._glfw.glfw.set_monitor_callback(None)

    @property
    def display_lost(self) -> bool:
        """True while the fullscreen window's monitor is gone."""
        return self._display_lost

    def _on_monitor(self, monitor: Any, event: int) -> None:
        glfw = self._glfw.glfw  # type: ignore[union-attr]
        name = _name(glfw, monitor)
        if event == glfw.DISCONNECTED and name == self._display_name and not self._display_lost:
            self._display_lost = True
            self._display_back = False
            self.stats.display_losses += 1
            log.warning(
                "display lost: monitor %r is gone; playing on without showing until it returns",
                name,
            )
            self._notify.status(f"display {name} lost: waiting for it")
        elif event == glfw.CONNECTED and self._display_lost:
            self._display_back = True

    def _reattach_display(self) -> None:
        """Once a monitor is back: the window fullscreen on it (the same name if connected,
        else the ``--monitor`` index), at its current mode."""
        if not self._display_back:
            return
        self._display_back = False
        glfw = self._glfw.glfw  # type: ignore[union-attr]
        monitors = list(glfw.get_monitors() or [])
        named = [m for m in monitors if _name(glfw, m) == self._display_name]
        if named:
            mon = named[0]
        elif 0 <= self.options.monitor < len(monitors):
            mon = monitors[self.options.monitor]
        else:  # a monitor came and went again: wait for the next event
            return
        mode = glfw.get_video_mode(mon)
        w, h = self.options.size or (int(mode.size.width), int(mode.size.height))
        glfw.set_window_monitor(self._win, mon, 0, 0, int(w), int(h), int(mode.refresh_rate))
        glfw.set_input_mode(self._win, glfw.CURSOR, glfw.CURSOR_HIDDEN)
        name = _name(glfw, mon)
        self._display_name = name
        self._display_lost = False
        log.info("display back: fullscreen on monitor %r (%dx%d)", name, w, h)
        self._notify.status(f"display {name} back: playing")

    def _unshown(self, planes: Planes, redraw: bool) -> None:
        """A frame come due while the display is gone: kept as the one on screen (the status
        reports it; the first turn after the display is back draws it), not drawn."""
        if not redraw:
            self.stats.unshown += 1
        idx, path = self._file
        assert self.renderer is not None
        x, y, z = (float(v) for v in self.renderer.eye)
        self._last_planes = planes
        self._drawn_key = None  # drawn afresh once the display is back
        self._pending_inputs.clear()  # applied, never shown: no latency to measure
        now = time.monotonic()
        self._shown = _Shown(idx, path, planes.time, self._still, now, (x, y, z), self._blackout)
