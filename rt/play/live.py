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

The commands, their checks and the parsers are in :mod:`viewcomp.rt.play.commands`, the
hub and the listener threads in :mod:`viewcomp.rt.play.listeners`; this module holds the
eye's smoothing (:class:`EyeState`) and gathers the whole live-input API under one name.

Conventions: an angle is in degrees, 90 = straight in front, < 90 the audience's right;
the eye for an angle is E = (d cos t, h, d sin t) with the rig's viewer distance d and
height h (metres, world frame of docs/MODEL.md, screen at z = 0).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from viewcomp.calib.world.eye import eye_from_angle, eye_to_polar
from viewcomp.rt.play.commands import (  # noqa: F401 (the live-input API, re-exported)
    ANGLE_ADDRESS,
    ANGLE_MAX,
    ANGLE_MIN,
    EYE_ADDRESS,
    EYE_LIMIT,
    EYES_ADDRESS,
    MAX_LINE,
    MAX_MESSAGES_PER_PACKET,
    MAX_SEEK,
    NORM_ADDRESS,
    NORM_RANGE,
    SHOW_ADDRESSES,
    STATUS_ADDRESS,
    Blackout,
    Command,
    EyeCommand,
    InputError,
    Next,
    NudgeAngle,
    Pause,
    Previous,
    Resume,
    Seek,
    SetAngle,
    SetAngleNorm,
    SetAudience,
    SetEye,
    ShowCommand,
    Status,
    check_angle,
    check_eye,
    check_eyes,
    check_flag,
    check_norm,
    check_norm_range,
    check_seek,
    parse_line,
    parse_osc_message,
    parse_osc_packet,
)
from viewcomp.rt.play.listeners import (  # noqa: F401 (re-exported)
    InputHub,
    LineReader,
    OscListener,
    Received,
    SourceCounts,
    parse_host_port,
)

# The angle <-> eye formula is viewcomp.calib.world.eye's; these names stay for callers.
polar_to_eye = eye_from_angle

SNAP = 1e-6  # metres: the smoothed eye snaps to the target when this close


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
