"""One capture session's devices and timing: the set-up at the first screen (latency, exposure
search, HDR bracket and its response) and :meth:`Session.take`, one checked-to-be-fresh capture
of a pattern (with a bracket, what its shortest stop clips taken again with the pattern
dimmed: :mod:`~viewcomp.calib.hw.dimming`)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from viewcomp.calib.hw.autoexposure import search_exposure
from viewcomp.calib.hw.bracket import Bracket
from viewcomp.calib.hw.dimming import Dimmer
from viewcomp.calib.hw.frames import FRAMES_DEEP, default_frames
from viewcomp.calib.hw.hdrresponse import choose_response, debevec_curve
from viewcomp.calib.hw.interface import Camera, Clock, DeviceError, Projector
from viewcomp.calib.hw.latency import MAX_LATENCY, measure_latency
from viewcomp.calib.hw.reader import FrameReader
from viewcomp.calib.io.patterns import table1_patterns
from viewcomp.calib.world.response import Response

Log = Callable[[str], None]


class Session:
    """The devices of one capture and how long to wait for a pattern (``latency`` s, measured
    by :meth:`prepare`, plus ``settle``); ``frames`` camera frames averaged per capture (None:
    chosen by :meth:`prepare` from the camera's frames,
    :func:`~viewcomp.calib.hw.frames.default_frames`)."""

    def __init__(
        self,
        projector: Projector,
        camera: Camera,
        clock: Clock,
        reader: FrameReader,
        log: Log,
        frames: int | None,
        settle: float,
    ) -> None:
        self.projector = projector
        self.camera = camera
        self.clock = clock
        self.reader = reader
        self.log = log
        self.frames = FRAMES_DEEP if frames is None else frames
        self._auto_frames = frames is None
        self.settle = settle
        self.latency = MAX_LATENCY
        self.bracket: Bracket | None = None
        self.dimmer: Dimmer | None = None
        #: the latest capture of black (with a bracket: merged linear), the dimmer's black level
        self.black: np.ndarray | None = None

    def prepare(
        self,
        search: bool,
        hdr_stops: tuple[float, ...] | None,
        response: Response,
        estimate_response: bool,
    ) -> Response | None:
        """With the first screen in place: measure the latency, search the exposure (when
        ``search``), set up the HDR bracket (``hdr_stops``; merged with ``response``, or with
        the response estimated from a bracket of the ramp when ``estimate_response``).
        Returns the estimated response, or None."""
        found = measure_latency(self.projector, self.reader, self.clock)
        if found is None:
            self.log(
                f"warning: {self.camera.name} saw no change from a black to a white screen; "
                f"waiting {MAX_LATENCY:g} s after each pattern"
            )
        else:
            self.latency = found
            self.log(
                f"projector -> camera latency: {found * 1000:.0f} ms (frames that start "
                "earlier are dropped)"
            )
        if self._auto_frames and self.reader.last is not None:
            self.frames = default_frames(self.reader.last)
            self.log(
                f"averaging {self.frames} frames per capture ({self.reader.last.bits}-bit "
                "frames; --frames to change it)"
            )
        if search:
            search_exposure(self.camera, self.projector, self.reader, self.latency, self.log)
        if hdr_stops is None:
            return None
        self.bracket = Bracket(
            self.camera,
            self.reader,
            self.clock,
            hdr_stops,
            response,
            self.log,
            self.projector.refresh_hz,
        )
        bracket = self.bracket
        self.dimmer = Dimmer(self._show, bracket.shortest, lambda: bracket.response, self.log)
        if not estimate_response:
            return None
        estimated = self._estimate_response()
        self.bracket.response = estimated
        return estimated

    def _estimate_response(self) -> Response:
        """The camera's response from a bracket of the ramp (:mod:`.hdrresponse`)."""
        assert self.bracket is not None
        w, h = self.projector.resolution
        ramp = table1_patterns(w, h)["ramp"]
        not_before = self.projector.show(ramp) + self.latency + self.settle
        raws, rels, linear = self.bracket.frames(self.frames, not_before, "response bracket")
        if linear:
            self.log(f"{self.camera.name} delivers raw (linear) frames: response linear")
            return Response(kind="linear")
        frames8 = [r if r.dtype == np.uint8 else np.rint(r / 257.0).astype(np.uint8) for r in raws]
        try:
            found, said = choose_response(debevec_curve(frames8, rels), frames8, rels)
        except (ValueError, np.linalg.LinAlgError) as e:
            raise DeviceError(
                f"the camera's response could not be estimated from the bracket ({e}): give "
                "--response (srgb, linear or a gamma) or a --rig with one"
            ) from e
        self.log(f"camera response estimated from the bracket (OpenCV's Debevec): {said}")
        return found

    def _show(self, pattern: np.ndarray) -> float:
        """Show ``pattern``; returns the clock time from which frames show it."""
        return self.projector.show(pattern) + self.latency + self.settle

    def take(self, pattern: np.ndarray, what: str) -> tuple[np.ndarray, np.ndarray | None]:
        """Show ``pattern`` and capture it: (encoded codes, None), or with a bracket (merged
        float32 linear, pixel-channels clipped in every frame and in its dimmed stops)."""
        not_before = self._show(pattern)
        if self.bracket is None:
            cam = self.camera
            have = cam.controls()
            # frames must be at the settings read back, unless the camera sets them itself
            # (--allow-auto with automatic exposure left on)
            auto = "auto_exposure" in have and cam.get("auto_exposure") != 0
            exp = cam.get("exposure") if "exposure" in have and not auto else None
            gain = cam.get("gain") if "gain" in have and not auto else None
            return self.reader.average(self.frames, not_before, exp, gain, what), None
        merged = self.bracket.grab(self.frames, not_before, what)
        if not pattern.any():
            self.black = merged[0]
        if self.dimmer is not None:
            merged = self.dimmer.recover(pattern, merged, self.black, self.frames, what)
        return merged
