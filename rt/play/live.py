"""Live eye input for playback: parsing, validation, smoothing and the listener threads.

No GL and no window here, so everything is testable on its own. Sources (docs/INTERFACES.md,
"Live eye input"):

- OSC over UDP: ``/viewcomp/angle f`` (degrees), ``/viewcomp/angle/norm f`` (0..1 onto a
  configured angle range) and ``/viewcomp/eye fff`` (metres), and the show control
  ``/viewcomp/pause``, ``/viewcomp/resume``, ``/viewcomp/seek f`` (seconds),
  ``/viewcomp/next``, ``/viewcomp/previous``, ``/viewcomp/blackout i`` and
  ``/viewcomp/status`` (answered to the sender), in a message or (possibly nested) bundles;
  bundle time tags are ignored (applied on arrival).
- Lines on standard input (or any file descriptor): ``angle 60``, ``norm 0.5``,
  ``eye 0.1 0.0 0.5``, ``pause``, ``resume``, ``seek 12.5``, ``next``, ``previous``,
  ``blackout 1``, ``status`` (commas also separate the numbers); blank lines and lines
  starting with ``#`` are ignored.
- Keys and mouse (from :mod:`viewcomp.rt.play.player`): relative moves of the angle, and the
  show control.

A malformed or out-of-range message raises :class:`InputError` in the pure parsers; the
listeners log it (rate-limited: the first few per source, then a count every few seconds)
and drop it, and playback goes on. Every valid command goes through one :class:`InputHub`
(thread-safe) to the playback thread, which applies it to an :class:`EyeState`: the target
jumps, the eye follows it with an exponential time constant so the picture never jumps.

Conventions: an angle is in degrees, 90 = straight in front, < 90 the audience's right;
the eye for an angle is E = (d cos t, h, d sin t) with the rig's viewer distance d and
height h (metres, world frame of docs/MODEL.md, screen at z = 0).
"""

from __future__ import annotations

import logging
import math
import os
import queue
import select
import socket
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from viewcomp.calib.errors import InputError
from viewcomp.calib.world import eye as eye_limits
from viewcomp.calib.world.eye import eye_from_angle, eye_to_polar

# The angle <-> eye formula is viewcomp.calib.world.eye's; these names stay for callers.
polar_to_eye = eye_from_angle

log = logging.getLogger(__name__)

ANGLE_ADDRESS = "/viewcomp/angle"
NORM_ADDRESS = "/viewcomp/angle/norm"
EYE_ADDRESS = "/viewcomp/eye"
EYES_ADDRESS = "/viewcomp/eyes"  # an audience: 3k floats (viewcomp track --faces all)
STATUS_ADDRESS = "/viewcomp/status"
NORM_RANGE = (30.0, 150.0)  # degrees that /viewcomp/angle/norm 0 and 1 map to by default
# The limits of an angle and an eye position are viewcomp.calib.world.eye's; relative moves
# (keys, mouse) stop at the angle's.
ANGLE_MIN, ANGLE_MAX = eye_limits.ANGLE_MIN, eye_limits.ANGLE_MAX
EYE_LIMIT = eye_limits.EYE_LIMIT
MAX_LINE = 256  # characters of one stdin line (longer: rejected)
MAX_MESSAGES_PER_PACKET = 64  # messages taken from one OSC bundle; the rest are rejected
SNAP = 1e-6  # metres: the smoothed eye snaps to the target when this close


@dataclass(frozen=True)
class SetAngle:
    """Move to viewing angle ``degrees`` at the rig's viewer distance and height."""

    degrees: float


@dataclass(frozen=True)
class SetEye:
    """Move to eye position ``eye`` = (x, y, z) metres."""

    eye: tuple[float, float, float]


@dataclass(frozen=True)
class NudgeAngle:
    """Turn the target by ``degrees`` around the screen centre, keeping distance and height."""

    degrees: float


@dataclass(frozen=True)
class SetAngleNorm:
    """Move to the angle ``value`` (0..1) of the way through the configured angle range."""

    value: float


@dataclass(frozen=True)
class SetAudience:
    """Compensate for every eye in ``eyes`` ((x, y, z) metres each, equal weights) at once
    (docs/MODEL.md section 6); one eye is :class:`SetEye` of it."""

    eyes: tuple[tuple[float, float, float], ...]


EyeCommand = SetAngle | SetEye | NudgeAngle | SetAngleNorm | SetAudience


@dataclass(frozen=True)
class Pause:
    """Hold the picture (the eye stays live)."""


@dataclass(frozen=True)
class Resume:
    """Play on from the held picture."""


@dataclass(frozen=True)
class Seek:
    """Go to ``seconds`` in the current file (``relative``: that many seconds on or back)."""

    seconds: float
    relative: bool = False


@dataclass(frozen=True)
class Next:
    """The next file of the playlist."""


@dataclass(frozen=True)
class Previous:
    """The previous file of the playlist."""


@dataclass(frozen=True)
class Blackout:
    """``on``: show black (playback goes on underneath); off: the picture again."""

    on: bool


@dataclass(frozen=True)
class Status:
    """Report what the player does: to ``reply_to`` (host, port) over OSC, or (None) stdout."""

    reply_to: tuple[str, int] | None = None


ShowCommand = Pause | Resume | Seek | Next | Previous | Blackout | Status
Command = EyeCommand | ShowCommand

# OSC address -> (stdin keyword, the command for no arguments, or None: takes a number)
SHOW_ADDRESSES: dict[str, tuple[str, ShowCommand | None]] = {
    "/viewcomp/pause": ("pause", Pause()),
    "/viewcomp/resume": ("resume", Resume()),
    "/viewcomp/next": ("next", Next()),
    "/viewcomp/previous": ("previous", Previous()),
    "/viewcomp/seek": ("seek", None),
    "/viewcomp/blackout": ("blackout", None),
    STATUS_ADDRESS: ("status", Status()),
}
MAX_SEEK = 360_000.0  # seconds (100 hours): a larger position is a typo


# ----------------------------------------------------------------------- validation
def _number(value: Any, what: str) -> float:
    """A finite float from an int/float (not bool, not str), else InputError."""
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise InputError(f"{what} must be a number, got {type(value).__name__} {value!r:.40}")
    v = float(value)
    if not math.isfinite(v):
        raise InputError(f"{what} must be finite, got {v}")
    return v


def check_angle(value: Any) -> float:
    """A viewing angle in degrees: a number (:func:`_number`) within the limits of
    :func:`viewcomp.calib.world.eye.check_angle`, which raises InputError here."""
    return eye_limits.check_angle(_number(value, "an angle"), "an angle", InputError)


def check_eye(values: Sequence[Any]) -> tuple[float, float, float]:
    """An eye position (x, y, z) metres: numbers within the limits of
    :func:`viewcomp.calib.world.eye.check_eye`, which raises InputError here."""
    if len(values) != 3:
        raise InputError(f"an eye position is three numbers x y z (metres), got {len(values)}")
    nums = [_number(v, "an eye coordinate") for v in values]
    x, y, z = eye_limits.check_eye(nums, "an eye position", InputError)
    return float(x), float(y), float(z)


def check_eyes(values: Sequence[Any]) -> SetAudience | SetEye:
    """Eye positions x1 y1 z1 x2 y2 z2 ... (1 to MAX_VIEWERS of them, each as
    :func:`check_eye`): a :class:`SetAudience`, or a :class:`SetEye` for one; else
    InputError."""
    from viewcomp.calib.world.audience import MAX_VIEWERS

    if not values or len(values) % 3 or len(values) > 3 * MAX_VIEWERS:
        raise InputError(
            f"eyes are 1 to {MAX_VIEWERS} positions x y z (metres), 3k numbers; got {len(values)}"
        )
    eyes = tuple(check_eye(values[i : i + 3]) for i in range(0, len(values), 3))
    return SetEye(eyes[0]) if len(eyes) == 1 else SetAudience(eyes)


def check_norm(value: Any) -> float:
    """A normalised angle in [0, 1]; else InputError."""
    v = _number(value, "a normalised angle")
    if not 0.0 <= v <= 1.0:
        raise InputError(f"a normalised angle is in [0, 1], got {v:g}")
    return v


def check_seek(value: Any) -> float:
    """A position in seconds, 0 .. MAX_SEEK; else InputError."""
    v = _number(value, "a position (seconds)")
    if not 0.0 <= v <= MAX_SEEK:
        raise InputError(f"a position is in [0, {MAX_SEEK:g}] seconds, got {v:g}")
    return v


def check_flag(value: Any, what: str) -> bool:
    """0 or 1 (int, float or bool) -> bool; else InputError."""
    if isinstance(value, bool):
        return value
    v = _number(value, what)
    if v not in (0.0, 1.0):
        raise InputError(f"{what} is 0 or 1, got {v:g}")
    return v == 1.0


def check_norm_range(lo: float, hi: float) -> tuple[float, float]:
    """A range of angles (degrees, each in (0, 180), lo != hi) for /viewcomp/angle/norm."""
    lo, hi = check_angle(lo), check_angle(hi)
    if lo == hi:
        raise InputError(f"a normalised-angle range needs two different angles, got {lo:g}:{hi:g}")
    return lo, hi


def _show_command(key: str, args: Sequence[Any], name: str) -> ShowCommand:
    """A show-control command from its keyword and arguments (already numbers)."""
    fixed = next((c for k, c in SHOW_ADDRESSES.values() if k == key), None)
    if fixed is not None:
        if args:
            raise InputError(f"{name} takes no arguments, got {len(args)}")
        return fixed
    if len(args) != 1:
        what = "seconds" if key == "seek" else "1 for black, 0 for the picture"
        raise InputError(f"{name} takes one number ({what}), got {len(args)}")
    if key == "seek":
        return Seek(check_seek(args[0]))
    return Blackout(check_flag(args[0], "blackout"))


_WORDS = {k for k, _ in SHOW_ADDRESSES.values()}
_EXPECTED_LINE = ("`angle DEG`, `norm 0..1`, `eye X Y Z`, `eyes X1 Y1 Z1 ...`, `pause`, "
                  "`resume`, `seek S`, `next`, `previous`, `blackout 0|1` or `status`")  # fmt: skip


# ----------------------------------------------------------------------- parsers
def parse_line(line: str) -> Command | None:
    """One stdin line -> a command, or None for a blank or ``#`` comment line.

    Grammar (case-insensitive keyword, numbers separated by spaces or commas)::

        angle DEG
        norm V            (0..1 onto the configured angle range)
        eye X Y Z
        eyes X1 Y1 Z1 X2 Y2 Z2 ...   (an audience; viewcomp track --faces all)
        pause | resume | next | previous | status
        seek SECONDS
        blackout 0|1

    Raises:
        InputError: anything else, numbers out of range, or a line over MAX_LINE characters.
    """
    if len(line) > MAX_LINE:
        raise InputError(f"line too long ({len(line)} > {MAX_LINE} characters)")
    text = line.strip()
    if not text or text.startswith("#"):
        return None
    words = text.replace(",", " ").split()
    key, args = words[0].lower(), words[1:]
    if key not in _WORDS | {"angle", "norm", "eye", "eyes"}:
        raise InputError(f"unknown command {words[0]!r:.30}; expected {_EXPECTED_LINE}")
    try:
        nums = [float(a) for a in args]
    except ValueError:
        raise InputError(f"not numbers in {text!r:.60}; expected {_EXPECTED_LINE}") from None
    if key == "angle":
        if len(nums) != 1:
            raise InputError(f"`angle` takes one number (degrees), got {len(nums)}")
        return SetAngle(check_angle(nums[0]))
    if key == "norm":
        if len(nums) != 1:
            raise InputError(f"`norm` takes one number (0..1), got {len(nums)}")
        return SetAngleNorm(check_norm(nums[0]))
    if key == "eye":
        return SetEye(check_eye(nums))
    if key == "eyes":
        return check_eyes(nums)
    return _show_command(key, nums, f"`{key}`")


def parse_osc_message(
    address: str, args: Sequence[Any], sender: tuple[str, int] | None = None
) -> Command:
    """An OSC message (address, arguments) -> a command.

    ``/viewcomp/angle`` takes one number (int, float or double), ``/viewcomp/angle/norm``
    one in [0, 1], ``/viewcomp/eye`` three, ``/viewcomp/eyes`` 3k (an audience);
    ``/viewcomp/seek`` one (seconds), ``/viewcomp/blackout`` one (0 or 1), the other
    show-control addresses none.
    ``/viewcomp/status`` is answered to ``sender`` (the datagram's source address).

    Raises:
        InputError: another address, a wrong count or type of arguments, out of range.
    """
    if address == ANGLE_ADDRESS:
        if len(args) != 1:
            raise InputError(f"{ANGLE_ADDRESS} takes one number (degrees), got {len(args)}")
        return SetAngle(check_angle(args[0]))
    if address == NORM_ADDRESS:
        if len(args) != 1:
            raise InputError(f"{NORM_ADDRESS} takes one number (0..1), got {len(args)}")
        return SetAngleNorm(check_norm(args[0]))
    if address == EYE_ADDRESS:
        return SetEye(check_eye(args))
    if address == EYES_ADDRESS:
        return check_eyes(args)
    if address in SHOW_ADDRESSES:
        key = SHOW_ADDRESSES[address][0]
        if key == "status":
            if args:
                raise InputError(f"{address} takes no arguments, got {len(args)}")
            return Status(sender)
        return _show_command(key, list(args), address)
    known = ", ".join([ANGLE_ADDRESS, NORM_ADDRESS, EYE_ADDRESS, EYES_ADDRESS, *SHOW_ADDRESSES])
    raise InputError(f"unknown OSC address {address!r:.60}; expected one of {known}")


def parse_osc_packet(
    data: bytes, sender: tuple[str, int] | None = None
) -> list[Command | InputError]:
    """A UDP datagram (from ``sender``) -> one result per OSC message in it.

    Raises:
        InputError: the datagram is not an OSC message or bundle at all.
    """
    from pythonosc.osc_packet import OscPacket

    if len(data) % 4:  # OSC 1.0: every packet is a multiple of 4 bytes (python-osc pads)
        raise InputError(f"not an OSC packet: {len(data)} bytes is not a multiple of 4")
    try:
        messages = OscPacket(data).messages
    except Exception as exc:  # python-osc raises ParseError and, on some junk, others
        raise InputError(f"not an OSC packet ({len(data)} bytes): {exc}") from None
    out: list[Command | InputError] = []
    for i, timed in enumerate(messages):
        if i >= MAX_MESSAGES_PER_PACKET:
            out.append(InputError(f"more than {MAX_MESSAGES_PER_PACKET} messages in a bundle"))
            continue
        msg = timed.message
        try:
            out.append(parse_osc_message(msg.address, list(msg.params), sender))
        except InputError as exc:
            out.append(exc)
    return out


# ----------------------------------------------------------------------- state
class EyeState:
    """The target eye (set by commands) and the smoothed eye that follows it.

    Args:
        distance, height: the rig's viewer distance and eye height (metres), used by
            :class:`SetAngle`.
        eye: the start position (3,) metres (target and current).
        tau: smoothing time constant in seconds (<= 0: the eye jumps to the target).

    ``norm_range`` (degrees for 0 and 1) maps :class:`SetAngleNorm` onto an angle.
    """

    def __init__(self, distance: float, height: float, eye: Sequence[float], tau: float):
        self.norm_range = NORM_RANGE
        self.distance = float(distance)
        self.height = float(height)
        self.target = np.asarray(eye, np.float64).copy()
        self.current = self.target.copy()
        self.tau = float(tau)
        self._t: float | None = None

    def apply(self, cmd: EyeCommand) -> None:
        """Set the target from an eye command (already validated).

        Raises:
            TypeError: a show-control command (the player's, not the eye's).
        """
        if isinstance(cmd, SetAngle):
            self.target = eye_from_angle(cmd.degrees, self.distance, self.height)
        elif isinstance(cmd, SetAngleNorm):
            lo, hi = self.norm_range
            self.target = eye_from_angle(lo + cmd.value * (hi - lo), self.distance, self.height)
        elif isinstance(cmd, SetEye):
            self.target = np.asarray(cmd.eye, np.float64)
        elif isinstance(cmd, NudgeAngle):
            angle, d, h = eye_to_polar(self.target)
            angle = min(ANGLE_MAX, max(ANGLE_MIN, angle + cmd.degrees))
            self.target = eye_from_angle(angle, d, h)
        else:
            raise TypeError(f"not an eye command: {cmd!r}")

    def jump(self) -> None:
        """Move the current eye to the target at once."""
        self.current = self.target.copy()

    def update(self, now: float) -> np.ndarray:
        """Advance the smoothed eye to time ``now`` (seconds, monotonic); returns it."""
        dt = 0.0 if self._t is None else max(now - self._t, 0.0)
        self._t = now
        if self.tau <= 0.0:
            self.current = self.target.copy()
        else:
            k = 1.0 - math.exp(-dt / self.tau)
            self.current = self.current + k * (self.target - self.current)
            if float(np.max(np.abs(self.target - self.current))) < SNAP:
                self.current = self.target.copy()
        return self.current

    @property
    def settled(self) -> bool:
        """True when the smoothed eye has reached the target."""
        return bool(np.array_equal(self.current, self.target))


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
            log.warning("%s: %d more malformed messages dropped (last: %s)", source,
                        self.hidden[source], message)  # fmt: skip
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
        raise InputError(f"an OSC address is HOST:PORT, e.g. 127.0.0.1:9000; got {text!r}")\
            from None  # fmt: skip
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
            raise InputError(f"cannot listen for OSC on {host}:{port}: {exc}; fix: use a free "
                             "port, e.g. --osc 127.0.0.1:9000") from exc  # fmt: skip
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
