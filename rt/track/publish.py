"""Where tracked eyes go: lines on a stream, OSC over UDP, or the player's input queue.

Formats (docs/INTERFACES.md, "viewcomp track"), metres in the world frame of docs/MODEL.md,
four decimals (0.1 mm):

- one eye (``--faces nearest``): the line ``eye X Y Z`` and the OSC message
  ``/viewcomp/eye fff``, exactly what ``viewcomp play`` reads on stdin and OSC
  (:func:`viewcomp.rt.play.live.parse_line`, :func:`viewcomp.rt.play.live.parse_osc_message`);
- all eyes (``--faces all``): the line ``eyes X1 Y1 Z1 X2 Y2 Z2 ...`` and the OSC message
  ``/viewcomp/eyes`` with 3k floats, nearest viewer first, always at least one eye.

A publisher is called with a (K, 3) array of eyes; it sends them only when the text differs
from what it sent last (a viewer standing still costs nothing downstream).
"""

from __future__ import annotations

import threading
from typing import Protocol, TextIO

import numpy as np

from viewcomp.rt.play.live import EYE_ADDRESS, EYES_ADDRESS  # the addresses the player reads


def format_eyes(eyes: np.ndarray, all_faces: bool) -> str:
    """The line for (K, 3) eyes: ``eye X Y Z`` (the first eye) or ``eyes X Y Z ...``."""
    e = np.asarray(eyes, np.float64).reshape(-1, 3)
    if not all_faces:
        e = e[:1]
    numbers = " ".join(f"{v:.4f}" for v in e.ravel())
    return f"{'eyes' if all_faces else 'eye'} {numbers}"


class Publisher(Protocol):
    """Something that sends eyes; :meth:`close` when done."""

    def publish(self, eyes: np.ndarray) -> bool: ...  # True when something was sent

    def close(self) -> None: ...


class LinePublisher:
    """Lines on a text stream (standard output), flushed at once so a pipe sees each."""

    def __init__(self, stream: TextIO, all_faces: bool = False) -> None:
        self.stream = stream
        self.all_faces = all_faces
        self._last = ""
        self.sent = 0

    def publish(self, eyes: np.ndarray) -> bool:
        """Write the line for ``eyes`` (K, 3) metres if it changed; True if written."""
        line = format_eyes(eyes, self.all_faces)
        if line == self._last:
            return False
        self.stream.write(line + "\n")
        self.stream.flush()
        self._last = line
        self.sent += 1
        return True

    def close(self) -> None:
        """Nothing to release (the stream is the caller's)."""


class OscPublisher:
    """OSC messages over UDP to (host, port): ``/viewcomp/eye`` or ``/viewcomp/eyes``."""

    def __init__(self, host: str, port: int, all_faces: bool = False) -> None:
        from pythonosc.udp_client import SimpleUDPClient

        self.client = SimpleUDPClient(host, port)
        self.all_faces = all_faces
        self._last = ""
        self.sent = 0
        self.failed = 0

    def publish(self, eyes: np.ndarray) -> bool:
        """Send the message for ``eyes`` (K, 3) metres if it changed; True if sent."""
        line = format_eyes(eyes, self.all_faces)
        if line == self._last:
            return False
        values = [float(v) for v in line.split()[1:]]
        try:
            self.client.send_message(EYES_ADDRESS if self.all_faces else EYE_ADDRESS, values)
        except OSError:  # nobody listening yet (ICMP refused) or a full buffer: next frame
            self.failed += 1
            return False
        self._last = line
        self.sent += 1
        return True

    def close(self) -> None:
        """Close the socket."""
        self.client._sock.close()


class HubPublisher:
    """Commands into a player's :class:`viewcomp.rt.play.live.InputHub` (source ``track``):
    the nearest eye as a ``SetEye`` or, with ``all_faces``, every face as a ``SetAudience``
    (one face: a ``SetEye``), validated as a stdin line would be."""

    source = "track"

    def __init__(self, hub: object, all_faces: bool = False) -> None:
        self.hub = hub
        self.all_faces = all_faces
        self._last = ""
        self._lock = threading.Lock()
        self.sent = 0

    def publish(self, eyes: np.ndarray) -> bool:
        """Queue the first eye of ``eyes`` (K, 3) (all of them with ``all_faces``) if it
        changed; True if queued."""
        from viewcomp.rt.play.live import InputError, parse_line

        line = format_eyes(eyes, self.all_faces)
        with self._lock:
            if line == self._last:
                return False
            self._last = line
        try:
            command = parse_line(line)
        except InputError as exc:
            self.hub.reject(self.source, exc)  # type: ignore[attr-defined]
            return False
        self.hub.put(self.source, command)  # type: ignore[attr-defined]
        self.sent += 1
        return True

    def close(self) -> None:
        """Nothing to release."""
