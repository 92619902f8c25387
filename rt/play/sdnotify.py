"""systemd's service notifications (sd_notify(3)) without a dependency, for the player as a
unit of ``Type=notify`` (examples/viewcomp-player.service).

systemd passes a datagram socket in ``NOTIFY_SOCKET`` (a path, or ``@name`` in the abstract
namespace) and, with ``WatchdogSec=``, the interval in ``WATCHDOG_USEC``. The player says
``READY=1`` once its first frame is on screen (so ``systemctl start`` returns when the
projector shows the picture, not when the process exists), ``WATCHDOG=1`` from its frame loop
(a loop that hangs - a stuck driver, a deadlock - is killed and restarted by systemd), and
``STATUS=`` lines that ``systemctl status`` shows. Outside systemd every call does nothing.
"""

from __future__ import annotations

import os
import socket
import time
from collections.abc import Mapping


class Notifier:
    """Sends sd_notify messages when ``NOTIFY_SOCKET`` is set (else a no-op).

    ``environ``: where to read ``NOTIFY_SOCKET``, ``WATCHDOG_USEC`` and ``WATCHDOG_PID``
    (default ``os.environ``). A send that fails (systemd gone) is dropped: notifications must
    never stop the show.
    """

    def __init__(self, environ: Mapping[str, str] | None = None) -> None:
        env = os.environ if environ is None else environ
        address = env.get("NOTIFY_SOCKET", "")
        self._address = "\0" + address[1:] if address.startswith("@") else address
        self._sock: socket.socket | None = None
        if self._address:
            self._sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM | socket.SOCK_CLOEXEC)
        usec = env.get("WATCHDOG_USEC", "")
        pid = env.get("WATCHDOG_PID", "")
        for_us = not pid or (pid.isdigit() and int(pid) == os.getpid())
        #: Seconds between watchdog pings systemd expects (None: no watchdog). Pinged at half
        #: of it, as sd_watchdog_enabled(3) advises.
        self.watchdog_interval: float | None = (
            int(usec) / 1e6 if usec.isdigit() and int(usec) > 0 and for_us else None
        )
        self._last_ping = -float("inf")

    @property
    def enabled(self) -> bool:
        """True under systemd (a notification socket was given)."""
        return self._sock is not None

    def send(self, *fields: str) -> bool:
        """Send ``KEY=value`` fields in one datagram; True if it was sent."""
        if self._sock is None:
            return False
        try:
            self._sock.sendto("\n".join(fields).encode("utf-8"), self._address)
        except OSError:
            return False
        return True

    def ready(self, status: str | None = None) -> bool:
        """The service is up (its first frame is on screen)."""
        return self.send("READY=1", *([f"STATUS={status}"] if status else []))

    def status(self, text: str) -> bool:
        """A one-line status for ``systemctl status``."""
        return self.send(f"STATUS={text}")

    def stopping(self) -> bool:
        """The service is shutting down on purpose."""
        return self.send("STOPPING=1")

    def watchdog(self, now: float | None = None) -> bool:
        """Ping the watchdog if half its interval has passed since the last ping (call it from
        every iteration of the frame loop; cheap when there is nothing to send)."""
        if self.watchdog_interval is None:
            return False
        t = time.monotonic() if now is None else now
        if t - self._last_ping < self.watchdog_interval / 2:
            return False
        self._last_ping = t
        return self.send("WATCHDOG=1")

    def close(self) -> None:
        """Close the socket."""
        if self._sock is not None:
            self._sock.close()
            self._sock = None
