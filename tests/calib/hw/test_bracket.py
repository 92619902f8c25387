"""HDR brackets in whole projector refresh periods: downward from a long base exposure, upward
from one refresh period when the base is only a period or two (webcams, machine vision), and
merged captures in the base's units. Expected exposures are worked out here by hand from the
refresh period; the emulator's frames report the exposure they were taken with."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from viewcomp.calib.emu.emulator import Emulator, open_emulator
from viewcomp.calib.emu.profiles import MONO12, WEBCAM
from viewcomp.calib.hw.bracket import Bracket, plan_bracket, stop_frames
from viewcomp.calib.hw.interface import ControlRange, DeviceError, Frame
from viewcomp.calib.hw.reader import FrameReader
from viewcomp.calib.io.hdr import DEFAULT_STOPS
from viewcomp.calib.world.response import parse_response

P = 1.0 / 60.0  # the refresh period at 60 Hz
SIZE = (160, 80)


def test_a_webcam_whose_white_needs_one_period_is_bracketed_upward() -> None:
    # the exposure search left 1 period at gain 1.69: 1/4 of that light is a quarter period
    stops, left_out, upward = plan_bracket(DEFAULT_STOPS, (P, 1.69), 60.0, (0.5, True, 8.0))
    assert upward and left_out == []
    assert [round(s.exposure / P, 9) for s in stops] == [1, 4, 16]
    assert [s.gain for s in stops] == [1.0, 1.0, 1.0]
    assert [s.rel for s in stops] == pytest.approx([1 / 1.69, 4 / 1.69, 16 / 1.69])


def test_a_long_base_is_bracketed_downward_as_asked() -> None:
    stops, left_out, upward = plan_bracket(DEFAULT_STOPS, (4 * P, 1.0), 60.0, (30.0, True, 64.0))
    assert not upward
    assert [round(s.exposure / P, 9) for s in stops] == [4, 1]
    assert left_out == [1 / 16, 1 / 64, 1 / 256]


def test_an_upward_stop_past_the_longest_exposure_takes_gain() -> None:
    stops, _, upward = plan_bracket(DEFAULT_STOPS, (2 * P, 1.0), 60.0, (0.05, True, 8.0))
    assert upward
    assert [round(s.exposure / P, 9) for s in stops] == [1, 3, 3]  # 0.05 s holds 3 periods
    assert [s.gain for s in stops] == pytest.approx([1.0, 4 / 3, 16 / 3])


def test_long_stops_take_fewer_frames_for_the_same_exposure_time() -> None:
    assert [stop_frames(8, e, 2 * P) for e in (P, 2 * P, 4 * P, 16 * P, 64 * P)] == [8, 8, 4, 1, 1]


def _manual(profile, exposure: float, gain: float, seed: int = 0) -> Emulator:
    emu = open_emulator(profile, "magenta", seed=seed, projector_size=SIZE)
    ctl = emu.camera.controls()
    for name in ("auto_exposure", "auto_white_balance"):
        if name in ctl:
            emu.camera.set(name, 0)
    emu.camera.set("exposure", exposure)
    emu.camera.set("gain", gain)
    return emu


def test_no_bracket_that_fits_is_refused_saying_why() -> None:
    # a camera whose exposure stops short of two periods and that has no gain to spare
    prof = replace(WEBCAM, exposure=ControlRange(1e-4, 0.03, 1e-4), gain=ControlRange(1, 1, 0))
    emu = _manual(prof, P, 1.0)
    reader = FrameReader(emu.camera, emu.clock, lambda _: None)
    with pytest.raises(DeviceError, match="no HDR bracket fits in whole projector refresh"):
        Bracket(emu.camera, reader, emu.clock, DEFAULT_STOPS, parse_response("srgb"), print, 60.0)


@pytest.mark.parametrize("profile", [WEBCAM, MONO12])
def test_upward_stops_are_whole_periods_and_merge_in_the_base_units(profile) -> None:
    base_exposure, base_gain = (P, 1.69) if profile is WEBCAM else (2 * P, 1.0)
    emu = _manual(profile, base_exposure, base_gain)
    cam = emu.camera
    kept: list[Frame] = []
    reader = FrameReader(cam, emu.clock, lambda _: None)
    frames_of = reader.frames

    def spy(*args, **kw) -> list[Frame]:
        got = frames_of(*args, **kw)
        kept.extend(got)
        return got

    reader.frames = spy  # type: ignore[method-assign]
    lines: list[str] = []
    response = parse_response("linear" if profile.linear else "srgb")
    bracket = Bracket(cam, reader, emu.clock, DEFAULT_STOPS, response, lines.append, 60.0)
    w, h = SIZE
    grey = np.full((h, w, 3), 160, np.uint8)
    t = emu.projector.show(grey)
    merged, clipped = bracket.grab(2, t + 0.2)
    assert any("taken upward" in line for line in lines), lines
    periods = sorted({round(f.exposure / P, 2) for f in kept})
    # the webcam's driver steps are 100 us: 16.7 ms is 1.002 periods
    assert all(abs(n - round(n)) <= 0.01 and round(n) >= 1 for n in periods), periods
    assert len(periods) >= 2
    assert cam.get("exposure") == pytest.approx(base_exposure, rel=1e-2)  # the base restored
    if profile.linear:
        # one frame at the base exposure, read directly: the merged capture is in its units
        t = emu.projector.show(grey)
        direct = reader.average(4, t + 0.2, cam.get("exposure")).astype(np.float64) / 65535.0
        lit = direct[..., 0] > 0.1
        assert not clipped[lit].any()
        ratio = float(np.median(merged[..., 0][lit] / direct[..., 0][lit]))
        assert ratio == pytest.approx(1.0, abs=0.03)
