"""Show control and keys of `viewcomp play`: pause, seek, next/previous, blackout, status;
the keyboard and mouse; status replies over OSC.

A pause, seek, next or previous is a *jump*: the main thread numbers it (a generation) and
hands (file, position) to the pump (:mod:`viewcomp.rt.play.playlist`), which reopens that
file there; the main thread drops what the pump had queued for older generations. A pause
is a jump to the frame on screen that is held until resume, so the audio of the old position
is dropped and resumes in step.
"""

from __future__ import annotations

import logging
import math
import socket
import threading
from typing import TYPE_CHECKING, Any

from viewcomp.rt.play.live import (
    Blackout,
    InputHub,
    Next,
    NudgeAngle,
    OscListener,
    Pause,
    Previous,
    Resume,
    Seek,
    SetAngle,
    Status,
)

if TYPE_CHECKING:
    from pathlib import Path

    from viewcomp.rt.play.embed import LiveRenderer
    from viewcomp.rt.play.player_options import PlayerOptions
    from viewcomp.rt.play.player_status import PlayerStatus, _Shown

log = logging.getLogger(__name__)

SHOW_TYPES = (Pause, Resume, Seek, Next, Previous, Blackout, Status)
SEEK_STEP = 10.0  # seconds per [ or ] key


class ShowControl:
    """Keys, mouse and the show-control commands of :class:`~viewcomp.rt.play.player.Player`
    (a mixin; main thread)."""

    options: PlayerOptions
    hub: InputHub
    renderer: LiveRenderer | None
    _paused: bool
    _blackout: bool
    _show_overlay: bool
    _show_next: bool
    _drag: tuple[float, float] | None
    _fb_size: tuple[int, int]
    _pending_inputs: list[float]
    _shown: _Shown | None
    _file: tuple[int, Path]
    _gen: int
    _jump: tuple[int, int, float] | None
    _jump_lock: threading.Lock
    _next: Any
    _origin: float | None
    _floor: float
    _osc: OscListener | None
    _sock: socket.socket | None
    _feedback_at: float

    if TYPE_CHECKING:  # the player's own, declared for the type checker

        def stop(self) -> None: ...

        def status(self) -> PlayerStatus: ...

    def _init_show_control(self) -> None:
        self._paused = False
        self._show_next = False  # paused: show the next frame (after a seek, next, previous)
        self._blackout = False
        self._feedback_at = -math.inf
        self._osc = None
        self._sock = None
        self._pending_inputs = []
        self._drag = None
        self._show_overlay = self.options.overlay

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
            # the first and the last input since the last present (two floats, however many
            # inputs arrive while nothing is presented: a paused still, a display gone)
            pending = self._pending_inputs
            if pending:
                pending[0], pending[1] = min(pending[0], item.at), max(pending[1], item.at)
            else:
                pending.extend((item.at, item.at))

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
