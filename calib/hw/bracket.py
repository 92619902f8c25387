"""HDR brackets for `viewcomp capture --hdr`: one capture taken at several exposures set
through the camera's ``exposure`` (and ``gain``) controls, read back, and merged into linear
light (:func:`~viewcomp.calib.io.hdr.merge_exposures`).

With the projector's refresh rate given, every exposure is a whole number of refresh periods
(a DLP's colour sub-frames and PWM bit planes only add up over whole periods): a relative
exposure that falls between whole periods takes the whole periods below it and makes up the
rest with the camera's gain (>= its base, 1), and one that needs less than one period at the
base gain is left out and said so (the projector's intensity is not scaled instead: scaled
codes change light by the projector's unknown response, not by the scale).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from viewcomp.calib.hw.frames import average_frames
from viewcomp.calib.hw.interface import Camera, Clock, DeviceError
from viewcomp.calib.hw.reader import FrameReader
from viewcomp.calib.io.hdr import check_stops, merge_exposures
from viewcomp.calib.world.response import Response

Log = Callable[[str], None]


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


class Bracket:
    """HDR captures: each one the camera's frames at every relative exposure of ``stops``,
    merged into float32 linear light in units of the camera's exposure and gain when the
    bracket starts (its base, restored after each capture). Frames are read through
    ``reader`` (only frames taken at the settings read back, after ``not_before``).
    ``refresh_hz``: the projector's, for whole refresh periods (module doc); None: exposures
    as asked.

    Raises (at construction or :meth:`grab`): DeviceError when the camera's exposure cannot
    be set or does not change.
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
        self.gain_max = have["gain"].high if self.has_gain else 1.0
        self.base = camera.get("exposure")
        self.base_gain = camera.get("gain") if self.has_gain else 1.0
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
        (each (H, W, 3) uint8/uint16 codes, their relative exposures as read back, whether
        the frames are linear). Exposures whose read-back repeats an earlier one are dropped
        (a driver at the end of its range)."""
        raws: list[np.ndarray] = []
        rels: list[float] = []
        left_out: list[float] = []
        linear = False
        light0 = self.base * self.base_gain
        try:
            for s in self.stops:
                plan = exposure_and_gain(light0 * s, self.refresh_hz, self.has_gain, self.gain_max)
                if plan is None:
                    left_out.append(s)
                    continue
                exposure = self._set("exposure", plan[0])
                gain = self._set("gain", plan[1]) if self.has_gain else 1.0
                rel = exposure * gain / light0
                if not (math.isfinite(rel) and rel > 0) or any(
                    abs(rel - r) <= 1e-6 * r for r in rels
                ):
                    continue
                start = max(not_before, self.clock.now())
                got = self.reader.frames(
                    frames, start, exposure, gain if self.has_gain else None, what
                )
                linear = got[0].linear
                raws.append(average_frames(got))
                rels.append(rel)
        finally:
            self._set("exposure", self.base)
            if self.has_gain:
                self._set("gain", self.base_gain)
        if len(rels) < 2 and left_out:
            period_ms = 1000.0 / (self.refresh_hz or 1.0)
            raise DeviceError(
                f"{self.camera.name}: no HDR bracket fits in whole projector refresh periods: "
                f"the base exposure ({self.base * 1000:.3g} ms at gain {self.base_gain:.3g}) "
                f"is already within a few periods ({period_ms:.3g} ms each), so "
                f"{', '.join(fraction(s) for s in left_out)} of it would need less light than "
                "one period at the camera's base gain (a DLP's colour sub-frames only add up "
                "over whole periods); lower the projector's brightness, close the aperture or "
                "add an ND filter so that the white screen needs a longer exposure, or "
                "capture without --hdr"
            )
        if len(rels) < 2:
            raise DeviceError(
                f"{self.camera.name} does not change its exposure (asked for {len(self.stops)} "
                f"relative exposures from {self.base:.6g} s, it reports the same): --hdr needs "
                "a camera whose exposure can be set; capture without --hdr"
            )
        if self.reported is None:
            self.reported = tuple(rels)
            self.log(
                "HDR bracket: relative exposures "
                + ", ".join(fraction(r) for r in rels)
                + f" of {self.base:.6g} s (as the camera reports them)"
            )
            if left_out:
                period_ms = 1000.0 / (self.refresh_hz or 1.0)
                self.log(
                    "HDR bracket: left out "
                    + ", ".join(fraction(s) for s in left_out)
                    + f": less light than one projector refresh period ({period_ms:.3g} ms) at "
                    "the camera's base gain; to keep them, lower the projector's brightness or "
                    "close the aperture and capture with a longer --exposure"
                )
        return raws, rels, linear

    def grab(
        self, frames: int, not_before: float, what: str = "a capture"
    ) -> tuple[np.ndarray, np.ndarray]:
        """One merged capture: ((H, W, 3) float32 linear, (H, W, 3) bool clipped in every
        frame) (see :meth:`frames`)."""
        raws, rels, _ = self.frames(frames, not_before, what)
        return merge_exposures(raws, rels, self.response)
