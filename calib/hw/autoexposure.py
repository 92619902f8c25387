"""The automatic exposure search of `viewcomp capture` (when ``--exposure`` is not given).

On the pattern that lights the screen most (full white), the camera's exposure is searched so
that the lit region's brightest codes sit just below clipping: the 99.5th percentile of the
frame's largest channel at :data:`TARGET` (80 %) of full scale. Exposures are whole numbers of
projector refresh periods when at least one period is needed (a DLP's colour sub-frames and PWM
bit planes only add up over whole periods). The gain stays at its base (1) unless the longest
exposure allowed (:data:`MAX_EXPOSURE`, or the control's range) is still too dark, or whole
periods step past the target (at 60 Hz a webcam has 16.7 or 33.3 ms: 43 % or 86 % of full
scale on one screen); then the whole periods below the target and the gain make up the rest.
A camera without gain whose whole periods cannot reach the target keeps the tried exposure
closest to it that does not clip (at least :data:`ACCEPT_LOW` of full scale). Each step reads
the control back and measures a fresh frame taken at it.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from viewcomp.calib.hw.frames import frame_rgb
from viewcomp.calib.hw.interface import Camera, DeviceError, Frame, Projector
from viewcomp.calib.hw.reader import FrameReader

TARGET = 0.80  # of full scale
TOLERANCE = 0.06
PERCENTILE = 99.5
MAX_EXPOSURE = 2.0  # s: longer makes a capture of ~40 patterns too slow
MAX_STEPS = 12
CLIPPED = 0.985
ACCEPT_LOW = 0.3  # of full scale: the least a closest-reachable exposure may give


def whole_periods(seconds: float, refresh_hz: float) -> float:
    """``seconds`` rounded to a whole number (>= 1) of refresh periods, when >= half a period;
    shorter exposures are returned as they are (no whole period fits)."""
    period = 1.0 / refresh_hz
    if seconds < 0.5 * period:
        return seconds
    return max(1, round(seconds / period)) * period


def bright_level(frame: Frame) -> float:
    """The :data:`PERCENTILE` of the frame's largest channel, 0..1 of full scale."""
    img = frame_rgb(frame).max(axis=2).astype(np.float32) / np.float32(frame.max_code)
    return float(np.percentile(img, PERCENTILE))


def _next_setting(
    name: str,
    level: float,
    light: float,
    linear: bool,
    ranges: tuple[float, float, float],
    refresh_hz: float,
) -> tuple[float, float]:
    """The next (exposure s, gain x) to try after a frame whose brightest codes were at
    ``level`` (0..1 of full scale) with ``light`` = exposure * gain (s); ``linear`` raw codes
    (else encoded ~ light^(1/2.2)); ``ranges`` (lowest exposure s, highest exposure s,
    highest gain x); exposures in whole refresh periods of ``refresh_hz`` (Hz) where one fits.

    Raises:
        DeviceError: even the shortest exposure would be too long (the white screen clips).
    """
    lo, hi, g_hi = ranges
    if level >= CLIPPED:
        want = light / 4  # clipped: how far is unknown, step down
    elif level <= 0.02:
        want = light * 8
    else:
        # encoded codes ~ light^(1/2.2); raw ones are linear
        power = 1.0 if linear else 2.2
        want = light * (TARGET / level) ** power
    new_gain = 1.0
    new_exp = want
    if want > hi:
        new_exp, new_gain = hi, min(g_hi, want / hi)
    if new_exp < lo:
        raise DeviceError(
            f"{name}: the white screen clips even at the shortest exposure "
            f"({lo * 1000:.3g} ms): lower the projector's brightness, close the lens's "
            "aperture or add an ND filter, and capture again"
        )
    new_exp = whole_periods(new_exp, refresh_hz)
    period = 1.0 / refresh_hz
    below = math.floor(want / period * (1 + 1e-9)) * period
    # light that still lands within the tolerance above the target
    slack = ((TARGET + TOLERANCE) / TARGET) ** (1.0 if linear else 2.2)
    if new_exp > want * slack and below >= period and g_hi > 1.0:
        # whole periods overshoot: the periods below the target, the gain for the rest
        new_exp, new_gain = below, min(g_hi, want / below)
    return new_exp, new_gain


def search_exposure(
    camera: Camera,
    projector: Projector,
    reader: FrameReader,
    latency: float,
    log: Callable[[str], None],
) -> tuple[float, float]:
    """Search the exposure (and if needed the gain) for the brightest pattern; returns the
    read-back (exposure s, gain x), which the camera is left at.

    Raises:
        DeviceError: the camera has no exposure control, or even the shortest exposure clips
            (or the longest at the highest gain is too dark); the message says what to change.
    """
    have = camera.controls()
    if "exposure" not in have:
        raise DeviceError(
            f"{camera.name} has no exposure control, so its exposure cannot be searched: "
            "capture with --exposure (if the backend sets it) or set it in the camera's own tool"
        )
    lo, hi = have["exposure"].low, min(have["exposure"].high, MAX_EXPOSURE)
    g_hi = have["gain"].high if "gain" in have else 1.0
    w, h = projector.resolution
    t = projector.show(np.full((h, w, 3), 255, np.uint8))
    exposure = camera.get("exposure")
    gain = camera.get("gain") if "gain" in have else 1.0
    level = 0.0
    best: tuple[float, float, float] | None = None  # (level, exposure, gain) unclipped
    for _ in range(MAX_STEPS):
        f = reader.fresh(max(t + latency, reader.clock.now()), exposure, None, "exposure search")
        exposure, gain = f.exposure, f.gain
        level = bright_level(f)
        if abs(level - TARGET) <= TOLERANCE:
            log(
                f"exposure search: {exposure * 1000:.4g} ms at gain {gain:.3g} puts the white "
                f"screen's brightest codes at {level:.0%} of full scale"
            )
            return exposure, gain
        if level < CLIPPED and (best is None or abs(level - TARGET) < abs(best[0] - TARGET)):
            best = (level, exposure, gain)
        new_exp, new_gain = _next_setting(
            camera.name, level, exposure * gain, f.linear, (lo, hi, g_hi), projector.refresh_hz
        )
        if math.isclose(new_exp, exposure, rel_tol=1e-3) and math.isclose(
            new_gain, gain, rel_tol=1e-3
        ):
            break  # at the end of the ranges
        exposure = camera.set("exposure", new_exp)
        if "gain" in have:
            gain = camera.set("gain", new_gain)
    if best is not None and best[0] >= ACCEPT_LOW:
        level, exposure, gain = best
        exposure = camera.set("exposure", exposure)
        if "gain" in have:
            gain = camera.set("gain", gain)
        log(
            f"exposure search: {exposure * 1000:.4g} ms at gain {gain:.3g} puts the white "
            f"screen's brightest codes at {level:.0%} of full scale, the closest to "
            f"{TARGET:.0%} that whole refresh periods reach without clipping"
        )
        return exposure, gain
    raise DeviceError(
        f"{camera.name}: the exposure search did not converge (last {exposure * 1000:.4g} ms at "
        f"gain {gain:.3g}: brightest codes at {level:.0%} of full scale, want {TARGET:.0%}): "
        "check that the camera sees the projected white screen and that the room is dark, or "
        "give --exposure"
    )
