"""Live commands for playback: what each eye and show-control command is, the checks of
their values and the parsers of stdin lines and OSC messages (docs/INTERFACES.md, "Live eye
input"). Pure functions, no threads: a malformed or out-of-range message raises
:class:`~viewcomp.calib.errors.InputError`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from viewcomp.calib.errors import InputError
from viewcomp.calib.world import eye as eye_limits

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


def _show_command(key: str, args: Sequence[Any], name: str) -> ShowCommand | None:
    """A show-control command from its keyword and arguments (already numbers); None for a
    trigger's release.

    A trigger (pause, resume, next, previous) takes no argument, or one: 1 acts and 0 does
    nothing, because the buttons of show-control consoles (QLab, TouchDesigner, Resolume)
    send 1 when pressed and 0 when released."""
    fixed = next((c for k, c in SHOW_ADDRESSES.values() if k == key), None)
    if fixed is not None:
        if not args:
            return fixed
        if len(args) == 1:
            press = _number(args[0], f"{name}'s argument")
            if press in (0.0, 1.0):
                return fixed if press == 1.0 else None
        raise InputError(
            f"{name} takes no argument, or one: 1 (a button pressed: act) or 0 (released: "
            f"nothing), got {', '.join(f'{a!r:.20}' for a in args)}"
        )
    if len(args) != 1:
        what = "seconds" if key == "seek" else "1 for black, 0 for the picture"
        raise InputError(f"{name} takes one number ({what}), got {len(args)}")
    if key == "seek":
        return Seek(check_seek(args[0]))
    return Blackout(check_flag(args[0], "blackout"))


_WORDS = {k for k, _ in SHOW_ADDRESSES.values()}
_EXPECTED_LINE = (
    "`angle DEG`, `norm 0..1`, `eye X Y Z`, `eyes X1 Y1 Z1 ...`, `pause`, "
    "`resume`, `seek S`, `next`, `previous`, `blackout 0|1` or `status`"
)


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
) -> Command | None:
    """An OSC message (address, arguments) -> a command.

    ``/viewcomp/angle`` takes one number (int, float or double), ``/viewcomp/angle/norm``
    one in [0, 1], ``/viewcomp/eye`` three, ``/viewcomp/eyes`` 3k (an audience);
    ``/viewcomp/seek`` one (seconds), ``/viewcomp/blackout`` one (0 or 1), the triggers
    (pause, resume, next, previous) none or one: 1 acts, 0 (a button's release) returns None.
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
            cmd = parse_osc_message(msg.address, list(msg.params), sender)
        except InputError as exc:
            out.append(exc)
            continue
        if cmd is not None:  # a button's release asks for nothing
            out.append(cmd)
    return out
