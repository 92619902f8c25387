"""HDR brackets for `viewcomp capture --hdr`: one capture taken at several exposures set
through the camera's ``exposure`` (and ``gain``) controls, read back, and merged into linear
light (:func:`~viewcomp.calib.io.hdr.merge_exposures`) in units of the light of the camera's
exposure and gain when the bracket is set up (its base: relative exposure 1).

With the projector's refresh rate given, every exposure is a whole number of refresh periods
(a DLP's colour sub-frames and PWM bit planes only add up over whole periods): a relative
exposure that falls between whole periods takes the whole periods below it and makes up the
rest with the camera's gain (>= its base, 1).

Two shapes of bracket (:func:`plan_bracket`):

- downward (a base of many refresh periods: a DSLR at 1/15 s): the asked relative exposures
  (1, 1/4, 1/16, ...) that fit in whole periods; one that needs less than one period at the
  base gain is left out and said so;
- upward, when fewer than two of the asked stops fit (a webcam or machine-vision camera whose
  white needs only a refresh period or two): the short stop is the least light whole periods
  give, one refresh period at gain 1 (relative exposure period / base light: below 1 when the
  search raised the gain or took two periods, so the white does not clip there), and the
  others are 4, 16, ... times it (the asked stops' ratios, read upward) for the dark parts, up
  to :data:`UPWARD_SPAN` times the short stop and within the camera's exposure and gain ranges.

The projector's intensity is not scaled for the bracket's stops: scaled codes change light by
the projector's response (not known to the capture, and not a power law on a DLP), not by the
scale. Only what the shortest stop clips is taken again with the pattern dimmed, at a light
ratio measured in the capture itself (:mod:`~viewcomp.calib.hw.dimming`). A stop
longer than the base exposure takes proportionally fewer frames (at least one): the same
exposure time per stop, so a 16-period stop does not multiply the capture's time by 16, and
its noise, averaged over as much light, is no worse than the base's.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from viewcomp.calib.hw.frames import average_frames
from viewcomp.calib.hw.interface import Camera, Clock, DeviceError
from viewcomp.calib.hw.reader import FrameReader
from viewcomp.calib.io.hdr import check_stops, merge_exposures
from viewcomp.calib.world.response import Response

Log = Callable[[str], None]

#: The most an upward bracket's longest stop may hold, in multiples of its short stop: 16
#: (4 stops of light) holds a black level of a few % of white in an 8-bit camera's well-coded
#: range, and keeps its longest exposure at 16 refresh periods (267 ms at 60 Hz).
UPWARD_SPAN = 16.0


@dataclass(frozen=True)
class Stop:
    """One exposure of a bracket: ``exposure`` (s, asked), ``gain`` (x, asked), ``rel`` the
    relative exposure asked (exposure * gain / the base's)."""

    exposure: float
    gain: float
    rel: float


def fraction(r: float) -> str:
    """``1/4`` for 0.25, ``2`` for 2."""
    return f"1/{1 / r:.4g}" if r < 1 else f"{r:.4g}"


def exposure_and_gain(
    light: float, refresh_hz: float | None, has_gain: bool, gain_max: float
) -> tuple[float, float] | None:
    """The (exposure s, gain x) that give ``light`` = exposure * gain: whole refresh periods
    (module doc), or ``(light, 1)`` without a refresh rate; None when no whole period fits at
    gain >= 1."""
    if refresh_hz is None:
        return light, 1.0
    period = 1.0 / refresh_hz
    if not has_gain:
        n = round(light / period)
        return (n * period, 1.0) if n >= 1 else None
    n = math.floor(light / period + 1e-9)
    if n < 1:
        return None
    gain = light / (n * period)
    if gain > gain_max:
        return None
    return n * period, max(1.0, gain)


def _upward_setting(
    light: float, period: float, exposure_high: float, has_gain: bool, gain_max: float
) -> tuple[float, float] | None:
    """(exposure s, gain x) for ``light`` (s at gain 1) in whole refresh periods of ``period``
    s, no longer than ``exposure_high`` s (the gain makes up the rest); None when neither the
    exposure nor the gain reaches it."""
    n = round(light / period)
    if n * period <= exposure_high * (1 + 1e-9):
        return n * period, 1.0
    n = math.floor(exposure_high / period + 1e-9)
    if n < 1 or not has_gain:
        return None
    gain = light / (n * period)
    return (n * period, gain) if gain <= gain_max else None


def plan_bracket(
    stops: tuple[float, ...],
    base: tuple[float, float],
    refresh_hz: float | None,
    ranges: tuple[float, bool, float],
) -> tuple[list[Stop], list[float], bool]:
    """The exposures of a bracket (module doc): the asked relative ``stops`` from the ``base``
    (exposure s, gain x) downward, or upward from one refresh period at gain 1 when fewer than
    two of them fit in whole periods of ``refresh_hz`` (None: exposures as asked).
    ``ranges``: (the camera's longest exposure s, whether it has a gain, its highest gain).

    Returns (the stops to take: downward in the asked order, upward shortest first; the asked
    stops left out (downward only); whether the bracket is upward).
    """
    exposure_high, has_gain, gain_max = ranges
    light0 = base[0] * base[1]
    down: list[Stop] = []
    left_out: list[float] = []
    for s in stops:
        setting = exposure_and_gain(light0 * s, refresh_hz, has_gain, gain_max)
        if setting is None:
            left_out.append(s)
        else:
            down.append(Stop(setting[0], setting[1], setting[0] * setting[1] / light0))
    if len(down) >= 2 or refresh_hz is None or not left_out:
        return down, left_out, False
    period = 1.0 / refresh_hz
    up: list[Stop] = []
    top = max(stops)
    for ratio in sorted(top / s for s in stops):
        if ratio > UPWARD_SPAN * (1 + 1e-9):
            break
        setting = _upward_setting(period * ratio, period, exposure_high, has_gain, gain_max)
        if setting is None:
            break
        up.append(Stop(setting[0], setting[1], setting[0] * setting[1] / light0))
    return up, [], True


def stop_frames(frames: int, exposure: float, base_exposure: float) -> int:
    """Frames to average at a stop of ``exposure`` s: ``frames`` up to the base exposure,
    proportionally fewer beyond it (the same exposure time, rounded), at least 1."""
    if exposure <= base_exposure * (1 + 1e-6):
        return frames
    return max(1, round(frames * base_exposure / exposure))


class Bracket:
    """HDR captures: each one the camera's frames at every stop of the bracket
    (:func:`plan_bracket` on the asked relative exposures ``stops``), merged into float32
    linear light in units of the camera's exposure and gain when the bracket is made (its
    base, restored after each capture). Frames are read through ``reader`` (only frames taken
    at the settings read back, after ``not_before``). ``refresh_hz``: the projector's, for
    whole refresh periods (module doc); None: exposures as asked.

    Raises (at construction or :meth:`grab`): DeviceError when the camera's exposure cannot
    be set or does not change, or no two stops fit in whole refresh periods.
    """

    def __init__(
        self,
        camera: Camera,
        reader: FrameReader,
        clock: Clock,
        stops: tuple[float, ...],
        response: Response,
        log: Log,
        refresh_hz: float | None = None,
    ) -> None:
        self.camera = camera
        self.reader = reader
        self.clock = clock
        self.stops = check_stops(stops)
        self.response = response
        self.log = log
        self.refresh_hz = refresh_hz
        have = camera.controls()
        if "exposure" not in have:
            raise DeviceError(
                f"{camera.name} has no exposure control: --hdr needs a camera whose exposure "
                "can be set; capture without --hdr (at an exposure where nothing clips)"
            )
        self.has_gain = "gain" in have
        gain_max = have["gain"].high if self.has_gain else 1.0
        self.base = camera.get("exposure")
        self.base_gain = camera.get("gain") if self.has_gain else 1.0
        ranges = (have["exposure"].high, self.has_gain, gain_max)
        self.plan, self.left_out, self.upward = plan_bracket(
            self.stops, (self.base, self.base_gain), refresh_hz, ranges
        )
        if len(self.plan) < 2:
            period_ms = 1000.0 / (refresh_hz or 1.0)
            raise DeviceError(
                f"{camera.name}: no HDR bracket fits in whole projector refresh periods "
                f"({period_ms:.3g} ms each): below the base exposure ({self.base * 1000:.3g} ms "
                f"at gain {self.base_gain:.3g}) no stop holds a whole period, and above it the "
                f"camera's exposure (up to {have['exposure'].high * 1000:.3g} ms) and gain "
                f"(up to {gain_max:.3g}) give no stop 4 times one period; capture without "
                "--hdr, or use a camera with a longer exposure or a gain"
            )
        self.reported: tuple[float, ...] | None = None

    def _set(self, control: str, value: float) -> float:
        try:
            return self.camera.set(control, value)
        except DeviceError as e:
            raise DeviceError(
                f"{self.camera.name}: the {control} cannot be set to {value:.6g} ({e}): --hdr "
                "needs a camera whose exposure can be set; capture without --hdr (at an "
                "exposure where nothing clips), or use another camera"
            ) from e

    def frames(
        self, frames: int, not_before: float, what: str = "a capture"
    ) -> tuple[list[np.ndarray], list[float], bool]:
        """The bracket's captures of what is on screen from ``not_before`` (clock s) on:
        (each (H, W, 3) uint8/uint16 codes, the mean of :func:`stop_frames` frames; their
        relative exposures as read back; whether the frames are linear). Stops whose
        read-back repeats an earlier one are dropped (a driver at the end of its range)."""
        raws: list[np.ndarray] = []
        rels: list[float] = []
        linear = False
        light0 = self.base * self.base_gain
        try:
            for stop in self.plan:
                exposure = self._set("exposure", stop.exposure)
                gain = self._set("gain", stop.gain) if self.has_gain else 1.0
                rel = exposure * gain / light0
                if not (math.isfinite(rel) and rel > 0) or any(
                    abs(rel - r) <= 1e-6 * r for r in rels
                ):
                    continue
                start = max(not_before, self.clock.now())
                n = stop_frames(frames, exposure, self.base)
                got = self.reader.frames(n, start, exposure, gain if self.has_gain else None, what)
                linear = got[0].linear
                raws.append(average_frames(got))
                rels.append(rel)
        finally:
            self._set("exposure", self.base)
            if self.has_gain:
                self._set("gain", self.base_gain)
        if len(rels) < 2:
            raise DeviceError(
                f"{self.camera.name} does not change its exposure (asked for {len(self.plan)} "
                f"exposures from {self.base:.6g} s, it reports the same): --hdr needs "
                "a camera whose exposure can be set; capture without --hdr"
            )
        if self.reported is None:
            self.reported = tuple(rels)
            self._report(rels, frames)
        if any(r.dtype != raws[0].dtype for r in raws):
            # one 8-bit frame stays uint8, a mean is uint16: the same 0..1 scale, one dtype
            raws = [
                r.astype(np.uint16) * np.uint16(257) if r.dtype == np.uint8 else r for r in raws
            ]
        return raws, rels, linear

    def shortest(self, frames: int, not_before: float, what: str) -> tuple[np.ndarray, float]:
        """The mean of ``frames`` frames at the bracket's least light (its first stop upward,
        its last downward) from ``not_before`` on: ((H, W, 3) uint8/uint16 codes, its relative
        exposure as read back). The base exposure and gain are restored after."""
        stop = min(self.plan, key=lambda s: s.rel)
        try:
            exposure = self._set("exposure", stop.exposure)
            gain = self._set("gain", stop.gain) if self.has_gain else 1.0
            start = max(not_before, self.clock.now())
            got = self.reader.frames(frames, start, exposure, gain if self.has_gain else None, what)
        finally:
            self._set("exposure", self.base)
            if self.has_gain:
                self._set("gain", self.base_gain)
        return average_frames(got), exposure * gain / (self.base * self.base_gain)

    def _report(self, rels: list[float], frames: int) -> None:
        """Log the bracket's stops (as read back) and what was left out, once."""
        period_ms = 1000.0 / (self.refresh_hz or 1.0)
        light0 = self.base * self.base_gain
        self.log(
            "HDR bracket: relative exposures "
            + ", ".join(fraction(r) for r in rels)
            + f" of {self.base:.6g} s at gain {self.base_gain:.4g} (as the camera reports them)"
        )
        if self.upward:
            self.log(
                "HDR bracket: taken upward, "
                + ", ".join(
                    f"{st.exposure * 1000:.4g} ms at gain {st.gain:.3g} "
                    f"(x{stop_frames(frames, st.exposure, self.base)} frames)"
                    for st in self.plan
                )
                + f": no stop below the base fits in whole projector refresh periods "
                f"({period_ms:.3g} ms); the shortest is one period at gain 1 "
                f"({fraction(self.plan[0].rel)} of the base's light "
                f"{light0 * 1000:.3g} ms x gain), the longer ones resolve the dark parts"
            )
        if self.left_out:
            self.log(
                "HDR bracket: left out "
                + ", ".join(fraction(s) for s in self.left_out)
                + f": less light than one projector refresh period ({period_ms:.3g} ms) at "
                "the camera's base gain; to keep them, lower the projector's brightness or "
                "close the aperture and capture with a longer --exposure"
            )

    def grab(
        self, frames: int, not_before: float, what: str = "a capture"
    ) -> tuple[np.ndarray, np.ndarray]:
        """One merged capture: ((H, W, 3) float32 linear, (H, W, 3) bool clipped in every
        frame) (see :meth:`frames`)."""
        raws, rels, _ = self.frames(frames, not_before, what)
        return merge_exposures(raws, rels, self.response)
