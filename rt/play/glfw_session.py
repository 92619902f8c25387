"""glfw for viewcomp's windows: one initialised session and the monitors it sees.

The player's window and the capture projector's both open through :class:`GlfwSession`:
glfw initialised with an error callback that keeps the last error (so a failed call is
reported with glfw's own reason, whatever ``glfw.ERROR_REPORTING`` says), terminated on
:meth:`GlfwSession.close`.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass
from typing import Any

log = logging.getLogger(__name__)

DISPLAY_FIX = (
    "run it on a desktop session (X11 or Wayland), or for tests under a virtual display: "
    "`Xvfb :99 -screen 0 1280x720x24 & export DISPLAY=:99` (Debian package xvfb)"
)


@dataclass(frozen=True)
class MonitorInfo:
    """A display as glfw sees it: index for ``--monitor``, name, mode, position."""

    index: int
    name: str
    width: int
    height: int
    refresh: int
    x: int
    y: int

    def __str__(self) -> str:
        hz = f" @ {self.refresh} Hz" if self.refresh else ""
        return f"{self.index}: {self.name} {self.width}x{self.height}{hz} at ({self.x}, {self.y})"


class GlfwSession:
    """glfw initialised with an error callback; terminated on :meth:`close` (idempotent).

    ``error`` is the exception type raised when glfw is missing or cannot open the display
    (the caller's: ``PlayerError``, ``DeviceError``); the message names the fix.
    """

    def __init__(self, error: type[Exception] = RuntimeError) -> None:
        try:
            import glfw
        except ImportError as exc:
            raise error(
                f"cannot load GLFW ({exc}); fix: install the glfw Python package and the GLFW 3 "
                "library (Debian: libglfw3)"
            ) from exc
        self.glfw: Any = glfw
        self.last_error = ""
        glfw.set_error_callback(self._error)
        if not glfw.init():
            glfw.set_error_callback(None)  # type: ignore[arg-type]  # None: no callback (glfw)
            raise error(
                f"cannot open the display ({self.last_error or 'glfw.init failed'}; "
                f"DISPLAY={os.environ.get('DISPLAY', '(unset)')}); fix: {DISPLAY_FIX}"
            )
        self._open = True

    def _error(self, code: int, description: bytes | str) -> None:
        text = (
            description.decode(errors="replace")
            if isinstance(description, bytes)
            else str(description)
        )
        self.last_error = f"glfw error {code}: {text}"
        log.debug("%s", self.last_error)

    def monitors(self) -> list[MonitorInfo]:
        """The connected monitors (index 0 is the primary)."""
        glfw = self.glfw
        out = []
        for i, m in enumerate(glfw.get_monitors() or []):
            mode = glfw.get_video_mode(m)
            x, y = glfw.get_monitor_pos(m)
            name = glfw.get_monitor_name(m)
            name = name.decode(errors="replace") if isinstance(name, bytes) else str(name)
            out.append(
                MonitorInfo(
                    i,
                    name,
                    int(mode.size.width),
                    int(mode.size.height),
                    int(mode.refresh_rate),
                    int(x),
                    int(y),
                )
            )
        return out

    def close(self) -> None:
        """Terminate glfw (every window it made is gone)."""
        if self._open:
            self.glfw.terminate()
            self.glfw.set_error_callback(None)
            self._open = False

    def __enter__(self) -> GlfwSession:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def list_monitors(error: type[Exception] = RuntimeError) -> list[MonitorInfo]:
    """The connected monitors (index 0 is the primary).

    Raises:
        error: no display (or no glfw).
    """
    with GlfwSession(error) as session:
        return session.monitors()
