"""HDR brackets for `viewcomp capture --hdr`: one capture taken at several exposures set
through the camera's ``exposure`` control (seconds, read back) and merged into linear light
(:func:`~viewcomp.calib.io.hdr.merge_exposures`).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from viewcomp.calib.hw.interface import Camera, Clock, DeviceError
from viewcomp.calib.hw.reader import FrameReader
from viewcomp.calib.io.hdr import check_stops, merge_exposures
from viewcomp.calib.world.response import Response

Log = Callable[[str], None]


def _fraction(r: float) -> str:
    return f"1/{1 / r:.4g}" if r < 1 else f"{r:.4g}"


class Bracket:
    """HDR captures: each one the camera's frames at every relative exposure of ``stops``
    (set through ``camera.set("exposure", ...)``, read back as the camera reports it), merged
    by :func:`~viewcomp.calib.io.hdr.merge_exposures` into float32 linear light in units of
    the camera's exposure when the bracket starts (its base, restored after each capture).
    Frames are read through ``reader`` (only frames taken at the exposure set, after
    ``not_before``).

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
    ) -> None:
        self.camera = camera
        self.reader = reader
        self.clock = clock
        self.stops = check_stops(stops)
        self.response = response
        self.log = log
        if "exposure" not in camera.controls():
            raise DeviceError(
                f"{camera.name} has no exposure control: --hdr needs a camera whose exposure "
                "can be set; capture without --hdr (at an exposure where nothing clips)"
            )
        self.base = camera.get("exposure")
        self.reported: tuple[float, ...] | None = None

    def _set(self, seconds: float) -> float:
        try:
            return self.camera.set("exposure", seconds)
        except DeviceError as e:
            raise DeviceError(
                f"{self.camera.name}: the exposure cannot be set to {seconds:.6g} s ({e}): --hdr "
                "needs a camera whose exposure can be set; capture without --hdr (at an "
                "exposure where nothing clips), or use another camera"
            ) from e

    def grab(
        self, frames: int, not_before: float, what: str = "a capture"
    ) -> tuple[np.ndarray, np.ndarray]:
        """One merged capture of what is on screen from ``not_before`` (clock s) on:
        ((H, W, 3) float32 linear, (H, W, 3) bool clipped in every frame). Exposures whose
        read-back repeats an earlier one are dropped (a driver at the end of its range)."""
        raws: list[np.ndarray] = []
        rels: list[float] = []
        try:
            for s in self.stops:
                got = self._set(self.base * s)
                rel = got / self.base
                if not (math.isfinite(rel) and rel > 0) or any(
                    abs(rel - r) <= 1e-6 * r for r in rels
                ):
                    continue
                start = max(not_before, self.clock.now())
                raws.append(self.reader.average(frames, start, exposure=got, what=what))
                rels.append(rel)
        finally:
            self._set(self.base)
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
                + ", ".join(_fraction(r) for r in rels)
                + f" of {self.base:.6g} s (as the camera reports them)"
            )
        return merge_exposures(raws, rels, self.response)
