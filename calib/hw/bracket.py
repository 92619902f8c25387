"""HDR brackets for `viewcomp capture --hdr`: one capture taken at several exposures set
through the camera's control and merged into linear light
(:func:`~viewcomp.calib.io.hdr.merge_exposures`), and the conversions between a driver's
exposure values and relative exposures.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from viewcomp.calib.hw.devices import Camera, DeviceError
from viewcomp.calib.io.hdr import check_stops, merge_exposures
from viewcomp.calib.world.response import Response

Log = Callable[[str], None]


def relative_exposure(base: float, value: float) -> float:
    """An exposure ``value`` relative to ``base``, both in the driver's units: linear (V4L2's
    100 us steps, the simulated camera's gain) when ``base`` > 0; log2 of seconds (DirectShow,
    MSMF: -13 .. 0) when ``base`` <= 0."""
    return value / base if base > 0 else 2.0 ** (value - base)


def exposure_value(base: float, relative: float) -> float:
    """The driver value that is ``relative`` times ``base`` (the inverse of
    :func:`relative_exposure`)."""
    return base * relative if base > 0 else base + math.log2(relative)


class Bracket:
    """HDR captures: each one the camera's frames at every relative exposure of ``stops``
    (set through :meth:`Camera.set_exposure`, read back as the camera reports it), merged
    by :func:`~viewcomp.calib.io.hdr.merge_exposures` into float32 linear light in units of
    the camera's exposure when the bracket starts (its base, restored after each capture).

    Raises (at construction or :meth:`grab`): DeviceError when the camera's exposure cannot
    be set or does not change.
    """

    def __init__(
        self, camera: Camera, stops: tuple[float, ...], response: Response, log: Log
    ) -> None:
        self.camera = camera
        self.stops = check_stops(stops)
        self.response = response
        self.log = log
        self.base = camera.get_exposure()
        self.reported: tuple[float, ...] | None = None

    def grab(self, frames: int) -> tuple[np.ndarray, np.ndarray]:
        """One merged capture: ((H, W, 3) float32 linear, (H, W, 3) bool clipped in every
        frame). Frames whose read-back exposure repeats an earlier one are dropped (a driver
        at the end of its range)."""
        raws: list[np.ndarray] = []
        rels: list[float] = []
        try:
            for s in self.stops:
                got = relative_exposure(
                    self.base, self.camera.set_exposure(exposure_value(self.base, s))
                )
                if not (math.isfinite(got) and got > 0) or any(
                    abs(got - r) <= 1e-6 * r for r in rels
                ):
                    continue
                raws.append(self.camera.grab(frames))
                rels.append(got)
        finally:
            self.camera.set_exposure(self.base)
        if len(rels) < 2:
            raise DeviceError(
                f"the camera does not change its exposure (asked for {len(self.stops)} relative "
                f"exposures from {self.base:g}, it reports the same): --hdr needs a camera whose "
                "exposure can be set; capture without --hdr"
            )
        if self.reported is None:
            self.reported = tuple(rels)
            self.log(
                "HDR bracket: relative exposures "
                + ", ".join(f"1/{1 / r:.4g}" if r < 1 else f"{r:.4g}" for r in rels)
                + f" of {self.base:g} (as the camera reports them)"
            )
        return merge_exposures(raws, rels, self.response)
