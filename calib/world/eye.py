"""Eye positions: a viewing angle is a shorthand for an eye position (docs/MODEL.md section 1).

The screen is the plane z = 0; the eye at angle theta is E = (d cos theta, h, d sin theta),
theta = 90 straight in front, theta < 90 to the audience's right. This module is the one home
of that formula (:func:`eye_from_angle`, and its inverse :func:`eye_to_polar`), of the limits
and of their checks; the only other copy of the formula is GLSL's (``vc_eye`` of
``shaders/mpv_pixel.glsl``), which takes the limits from here (:func:`glsl_defines`).

The one validation of where a viewer can be, used by every command, the player's live input,
the embedding API and angle tracks (docs/INTERFACES.md, "Limits"):

- a viewing angle is a finite number of degrees in [ANGLE_MIN, ANGLE_MAX] = [1, 179];
- an eye position is three finite numbers (metres) with z >= EYE_MIN_Z (in front of the
  screen, not in its plane) and each |coordinate| <= EYE_LIMIT;
- a track's times are finite and strictly increasing, its angles valid angles.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from viewcomp.calib.errors import EyeError, ViewcompError

ANGLE_MIN, ANGLE_MAX = 1.0, 179.0  # degrees; 0 and 180 lie in the screen's plane
EYE_MIN_Z = 0.05  # metres in front of the screen: closer, the view terms degenerate
EYE_LIMIT = 50.0  # metres: |x|, |y|, |z| of an eye position

# The error a check raises: EyeError, or the caller's own (a track's TrackError, a live
# command's InputError), so that a value is checked once and refused once, never re-raised.
ErrorClass = type[ViewcompError]


def _finite(value: Any, what: str, fix: str, error: ErrorClass = EyeError) -> float:
    if isinstance(value, bool | str | bytes) or value is None:
        raise error(f"{what} must be a number, got {value!r:.40} - {fix}")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise error(f"{what} must be a number, got {value!r:.40} - {fix}") from None
    if not math.isfinite(v):
        raise error(f"{what} must be a finite number, got {v} - {fix}")
    return v


def check_angle(value: Any, what: str = "a viewing angle", error: ErrorClass = EyeError) -> float:
    """A viewing angle in degrees, finite and in [ANGLE_MIN, ANGLE_MAX]; else ``error``."""
    v = _finite(value, what, f"give degrees from {ANGLE_MIN:g} to {ANGLE_MAX:g}", error)
    if not ANGLE_MIN <= v <= ANGLE_MAX:
        raise error(
            f"{what} is {v:g} degrees; it must be in [{ANGLE_MIN:g}, {ANGLE_MAX:g}] "
            "(90 = in front of the screen, < 90 to the audience's right) - give an angle "
            f"from {ANGLE_MIN:g} to {ANGLE_MAX:g}"
        )
    return v


def check_eye(
    values: Sequence[Any] | np.ndarray, what: str = "an eye position", error: ErrorClass = EyeError
) -> np.ndarray:
    """An eye position (3,) float64 metres: finite, z >= EYE_MIN_Z, |each| <= EYE_LIMIT; else
    ``error``."""
    vals = list(np.asarray(values, dtype=object).ravel()) if not isinstance(values, str) else []
    if len(vals) != 3:
        raise error(f"{what} is three numbers X,Y,Z in metres, got {values!r:.60}")
    e = np.array([_finite(v, what, "give X,Y,Z in metres, e.g. 0.1,0.0,0.5", error) for v in vals])
    shown = ",".join(f"{v:g}" for v in e)
    if np.max(np.abs(e)) > EYE_LIMIT:
        raise error(
            f"{what} ({shown}) is more than {EYE_LIMIT:g} m from the screen - give metres, "
            "e.g. 0.1,0.0,0.5"
        )
    if e[2] < EYE_MIN_Z:
        raise error(
            f"{what} ({shown}) is not in front of the screen: z must be at least "
            f"{EYE_MIN_Z:g} m (+z points toward the audience) - give a z of {EYE_MIN_Z:g} or more"
        )
    return e


def check_track(
    times: Sequence[float] | np.ndarray,
    degrees: Sequence[float] | np.ndarray,
    what: str = "a track",
    error: ErrorClass = EyeError,
) -> tuple[np.ndarray, np.ndarray]:
    """(seconds, degrees) samples: equal-length 1-D, at least one, times finite and strictly
    increasing, every angle valid (:func:`check_angle`). Returns both as float64; else
    ``error``."""
    t = np.asarray(times, np.float64)
    d = np.asarray(degrees, np.float64)
    if t.ndim != 1 or t.shape != d.shape or not len(t):
        raise error(f"{what} needs (seconds, degrees) rows, got shapes {t.shape}, {d.shape}")
    for i, (ti, di) in enumerate(zip(t, d, strict=True)):
        _finite(ti, f"{what}: the time of row {i + 1}", "give seconds", error)
        check_angle(di, f"{what}: the angle at {ti:g} s", error)
    if np.any(np.diff(t) <= 0):
        i = int(np.argmax(np.diff(t) <= 0))
        raise error(f"{what}: time {t[i + 1]:g} s is not after {t[i]:g} s - times must increase")
    return t, d


def eye_from_angle(
    theta_deg: float | np.ndarray, distance: float | np.ndarray, height: float | np.ndarray
) -> np.ndarray:
    """E_theta = (d cos theta, h, d sin theta): theta = 90 is straight in front, < 90 right.

    Args:
        theta_deg: viewing angle in degrees (see :func:`check_angle` for the valid range).
        distance: d, metres from the screen centre.
        height: h, eye height y in metres.

    Returns:
        float64 eye positions in metres: (3,) for scalars; (..., 3) for arrays, which
        broadcast together (e.g. a walk's angles, distances and heights over time).
    """
    t = np.deg2rad(theta_deg)
    parts = np.broadcast_arrays(distance * np.cos(t), height, distance * np.sin(t))
    return np.stack(parts, axis=-1).astype(np.float64)


def eye_to_polar(eye: np.ndarray | Sequence[float]) -> tuple[float, float, float]:
    """(angle degrees, distance d, height h) of an eye: the inverse of :func:`eye_from_angle`
    (E = (d cos theta, h, d sin theta)); the angle in (-180, 180], not checked."""
    x, y, z = (float(v) for v in eye)
    return math.degrees(math.atan2(z, x)), math.hypot(x, z), y


def glsl_defines() -> dict[str, str]:
    """The limits as GLSL ``#define`` values (``VC_ANGLE_MIN``, ``VC_ANGLE_MAX``, degrees), so a
    shader that turns an angle into an eye clamps it to these and no others."""
    return {"VC_ANGLE_MIN": f"{ANGLE_MIN:.1f}", "VC_ANGLE_MAX": f"{ANGLE_MAX:.1f}"}
