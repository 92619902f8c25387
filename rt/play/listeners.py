"""The listener threads of live input: OSC over UDP and lines on a file descriptor, each
parsed (:mod:`viewcomp.rt.play.commands`) into one thread-safe :class:`InputHub` that the
playback thread drains; malformed messages are logged (rate-limited) and dropped.
"""

from __future__ import annotations

import logging
import os
import queue
import select
import socket
import threading
import time
from dataclasses import dataclass, field

from viewcomp.calib.errors import InputError
from viewcomp.rt.play.commands import (
    MAX_LINE,
    Command,
    parse_line,
    parse_osc_packet,
)

log = logging.getLogger(__name__)


# ----------------------------------------------------------------------- hub
@dataclass
class SourceCounts:
    """Per source: commands received valid, applied by the playback thread, rejected."""

    received: int = 0
    applied: int = 0
    rejected: int = 0
    last_error: str = ""


@dataclass(frozen=True)
class Received:
    """A valid command, where it came from and when it arrived (time.monotonic seconds)."""

    source: str
    command: Command
    at: float


class _RateLimit:
    """Log the first ``burst`` rejections per source, then one summary per ``period`` s."""

    def __init__(self, burst: int = 10, period: float = 5.0) -> None:
        self.burst, self.period = burst, period
        self.count: dict[str, int] = {}
        self.hidden: dict[str, int] = {}
        self.last: dict[str, float] = {}

    def __call__(self, source: str, message: str) -> None:
        n = self.count.get(source, 0) + 1
        self.count[source] = n
        if n <= self.burst:
            log.warning("%s: dropped: %s", source, message)
            if n == self.burst:
                log.warning("%s: further dropped messages are counted, not logged", source)
            self.last[source] = time.monotonic()
            return
        self.hidden[source] = self.hidden.get(source, 0) + 1
        now = time.monotonic()
        if now - self.last.get(source, 0.0) >= self.period:
            log.warning(
                "%s: %d more malformed messages dropped (last: %s)",
                source,
                self.hidden[source],
                message,
            )
            self.hidden[source] = 0
            self.last[source] = now


class InputHub:
    """Where every input source delivers: valid commands queued, rejections counted.

    ``put``/``reject`` may be called from any thread; ``drain`` from the playback thread,
    which then calls ``applied`` for what it applied. Counters are per source name.
    """

    def __init__(self) -> None:
        self._queue: queue.SimpleQueue[Received] = queue.SimpleQueue()
        self._lock = threading.Lock()
        self.counts: dict[str, SourceCounts] = {}
        self._log = _RateLimit()

    def _c(self, source: str) -> SourceCounts:
        c = self.counts.get(source)
        if c is None:
            c = self.counts[source] = SourceCounts()
        return c

    def put(self, source: str, command: Command) -> None:
        """Queue a valid command from ``source``."""
        with self._lock:
            self._c(source).received += 1
        self._queue.put(Received(source, command, time.monotonic()))

    def reject(self, source: str, error: Exception | str) -> None:
        """Count and (rate-limited) log a malformed or out-of-range message."""
        text = str(error)
        with self._lock:
            c = self._c(source)
            c.rejected += 1
            c.last_error = text
            self._log(source, text)

    def drain(self, limit: int = 100_000) -> list[Received]:
        """Everything queued so far (at most ``limit``), oldest first. Non-blocking."""
        out: list[Received] = []
        while len(out) < limit:
            try:
                out.append(self._queue.get_nowait())
            except queue.Empty:
                break
        return out

    def applied(self, item: Received) -> None:
        """Record that the playback thread applied ``item``."""
        with self._lock:
            self._c(item.source).applied += 1

    def snapshot(self) -> dict[str, SourceCounts]:
        """A copy of the counters."""
        with self._lock:
            return {k: SourceCounts(**vars(v)) for k, v in self.counts.items()}


# ----------------------------------------------------------------------- listeners
def parse_host_port(text: str, default_host: str = "127.0.0.1") -> tuple[str, int]:
    """'HOST:PORT', ':PORT' or 'PORT' (and '[::1]:PORT') -> (host, port 0..65535).

    Raises:
        InputError: not of that form.
    """
    text = text.strip()
    host, sep, port_s = text.rpartition(":")
    if not sep:
        host, port_s = "", text
    host = host.strip("[]") or default_host
    try:
        port = int(port_s)
    except ValueError:
        raise InputError(
            f"an OSC address is HOST:PORT, e.g. 127.0.0.1:9000; got {text!r}"
        ) from None
    if not 0 <= port <= 65535:
        raise InputError(f"a UDP port is 0..65535, got {port}")
    return host, port


class OscListener:
    """A UDP socket on (host, port) and a thread turning datagrams into commands.

    Port 0 takes a free port (see :attr:`address`). Use :meth:`start` / :meth:`stop`, or a
    ``with`` block. Datagrams over 64 KiB do not exist in UDP; every datagram is parsed with
    :func:`parse_osc_packet` and each message is put to the hub or rejected.
    """

    source = "osc"

    def __init__(self, hub: InputHub, host: str = "127.0.0.1", port: int = 9000) -> None:
        self.hub = hub
        family = socket.AF_INET6 if ":" in host else socket.AF_INET
        self.sock = socket.socket(family, socket.SOCK_DGRAM)
        self._send_lock = threading.Lock()
        try:
            self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
            self.sock.bind((host, port))
        except OSError as exc:
            self.sock.close()
            raise InputError(
                f"cannot listen for OSC on {host}:{port}: {exc}; fix: use a free "
                "port, e.g. --osc 127.0.0.1:9000"
            ) from exc
        self.sock.settimeout(0.1)
        self.address: tuple[str, int] = self.sock.getsockname()[:2]
        self.packets = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="viewcomp-osc", daemon=True)

    def start(self) -> OscListener:
        """Start the listening thread."""
        self._thread.start()
        return self

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                data, sender = self.sock.recvfrom(65536)
            except TimeoutError:
                continue
            except OSError:
                if self._stop.is_set():
                    return
                continue
            self.packets += 1
            try:
                results = parse_osc_packet(data, tuple(sender[:2]))
            except InputError as exc:
                self.hub.reject(self.source, exc)
                continue
            for r in results:
                if isinstance(r, InputError):
                    self.hub.reject(self.source, r)
                else:
                    self.hub.put(self.source, r)

    def send(self, data: bytes, address: tuple[str, int]) -> None:
        """Send a datagram from the listening socket (replies reach the sender's port)."""
        with self._send_lock:
            try:
                self.sock.sendto(data, address)
            except OSError as exc:  # an unreachable controller must not stop playback
                log.warning("osc: cannot send to %s:%d: %s", *address, exc)

    def stop(self) -> None:
        """Stop the thread and close the socket."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=2.0)
        self.sock.close()

    def __enter__(self) -> OscListener:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()


@dataclass
class _LineBuffer:
    """Splits a byte stream into lines; an over-long line is reported once, then skipped."""

    limit: int = MAX_LINE
    data: bytearray = field(default_factory=bytearray)
    skipping: bool = False

    def feed(self, chunk: bytes) -> list[bytes | None]:
        """Complete lines in ``chunk`` (None stands for an over-long line)."""
        out: list[bytes | None] = []
        self.data += chunk
        while True:
            nl = self.data.find(b"\n")
            if nl < 0:
                if len(self.data) > self.limit and not self.skipping:
                    out.append(None)
                    self.skipping = True
                if self.skipping:
                    self.data.clear()
                return out
            line = bytes(self.data[:nl])
            del self.data[: nl + 1]
            if self.skipping:
                self.skipping = False
                continue
            out.append(None if len(line) > self.limit else line)

    def tail(self) -> bytes | None:
        """What is left at end of stream (a last line without newline)."""
        if self.skipping or not self.data:
            return None
        return bytes(self.data)


class LineReader:
    """A thread reading command lines from a file descriptor (standard input by default).

    Reads with ``select`` and a timeout so that :meth:`stop` ends it promptly; end of file
    ends it quietly. Bytes that are not UTF-8 and over-long lines are rejected.
    """

    source = "stdin"

    def __init__(self, hub: InputHub, fd: int | None = None) -> None:
        self.hub = hub
        self.fd = 0 if fd is None else fd
        self.lines = 0
        self.eof = False
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="viewcomp-stdin", daemon=True)

    def start(self) -> LineReader:
        """Start the reading thread."""
        self._thread.start()
        return self

    def _handle(self, raw: bytes | None) -> None:
        self.lines += 1
        if raw is None:
            self.hub.reject(self.source, f"line too long (> {MAX_LINE} characters)")
            return
        try:
            text = raw.decode("utf-8").rstrip("\r")
            cmd = parse_line(text)
        except UnicodeDecodeError:
            self.hub.reject(self.source, "not UTF-8 text")
            return
        except InputError as exc:
            self.hub.reject(self.source, exc)
            return
        if cmd is not None:
            self.hub.put(self.source, cmd)

    def _run(self) -> None:
        buf = _LineBuffer()
        while not self._stop.is_set():
            try:
                ready, _, _ = select.select([self.fd], [], [], 0.1)
            except (OSError, ValueError):
                break  # closed descriptor
            if not ready:
                continue
            try:
                chunk = os.read(self.fd, 65536)
            except OSError:
                break
            if not chunk:
                tail = buf.tail()
                if tail is not None:
                    self._handle(tail)
                break
            for raw in buf.feed(chunk):
                self._handle(raw)
        self.eof = True

    def stop(self) -> None:
        """Stop the thread (it is a daemon; the descriptor is not closed)."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=2.0)

    def __enter__(self) -> LineReader:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()
