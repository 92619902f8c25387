"""The capture procedure against the simulated rig's real-device behaviour: presentation sync
(latency, queued frames), locking, the exposure search, retries and a dead camera, HDR in whole
refresh periods, the response from a bracket, and mono cameras."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from viewcomp.calib.errors import FitError
from viewcomp.calib.fit.calibrate import calibrate
from viewcomp.calib.hw import session as session_mod
from viewcomp.calib.hw.autoexposure import TARGET, bright_level, search_exposure
from viewcomp.calib.hw.bracket import Bracket
from viewcomp.calib.hw.camlock import lock_controls
from viewcomp.calib.hw.clock import SimClock
from viewcomp.calib.hw.interface import DeviceError
from viewcomp.calib.hw.procedure import run_capture
from viewcomp.calib.hw.reader import FrameReader
from viewcomp.calib.hw.session import Session
from viewcomp.calib.hw.simrig import SimulatedRig
from viewcomp.calib.io.captureset import read_capture_set
from viewcomp.calib.io.checks import is_mono_set
from viewcomp.calib.io.hdr import DEFAULT_STOPS
from viewcomp.calib.sim.simcamera import scaled_camera_rig, written_rig
from viewcomp.calib.sim.simulator import (
    CameraPhysics,
    Simulator,
    make_screen,
    simulation_rig,
    white_screen,
)
from viewcomp.calib.world.response import parse_response
from viewcomp.calib.world.rig import load_rig

SIZE = (160, 80)


def _rig(response: str | float = "srgb", exposure: float = 0.8, **kw) -> SimulatedRig:
    rig = simulation_rig()
    rig = scaled_camera_rig(replace(rig, projector=replace(rig.projector, resolution=SIZE)), SIZE)
    rig = replace(rig, camera=replace(rig.camera, response=response))
    sim = Simulator(rig=rig, seed=5, camera=CameraPhysics(exposure=exposure))
    screen = make_screen("green", "matte", shape=sim.shape)
    return SimulatedRig(sim, {"white": white_screen(), "screen": screen}, **kw)


def _session(dev: SimulatedRig, frames: int = 1) -> Session:
    reader = FrameReader(dev.camera, dev.clock, lambda _: None)
    return Session(dev.projector, dev.camera, dev.clock, reader, lambda _: None, frames, 0.0)


def _patterns() -> list[np.ndarray]:
    w, h = SIZE
    black = np.zeros((h, w, 3), np.uint8)
    white = np.full((h, w, 3), 255, np.uint8)
    half = black.copy()
    half[:, : w // 2] = 255
    return [black, white, black, half, white, black, white]


def _halves(a: np.ndarray, b: np.ndarray) -> float:
    """The larger difference of the mean levels of the left and right halves (noise averages
    out; a frame of another pattern does not)."""
    w = a.shape[1] // 2
    return max(
        abs(float(a[:, :w].mean() - b[:, :w].mean())), abs(float(a[:, w:].mean() - b[:, w:].mean()))
    )


def test_every_kept_frame_shows_its_pattern_despite_latency_and_a_queue() -> None:
    """A projector 0.2 s late and a driver keeping 4 frames (short exposures at 30 fps): each
    capture equals what a rig without either gives; with the latency not waited for, the
    captures show the previous pattern (the check can fail)."""
    kw = dict(unit_exposure=0.02, exposure=0.8)
    ideal = _session(_rig(latency=0.0, queue=1, **kw), frames=2)
    ideal.latency = 0.0
    laggy_dev = _rig(latency=0.2, queue=4, **kw)
    laggy = _session(laggy_dev, frames=2)
    laggy.prepare(False, None, parse_response("srgb"), False)
    # the latency the session measured on the rig's simulated clock (no wall time: a busy
    # machine cannot move it) covers the one the simulated projector was given
    assert isinstance(laggy_dev.clock, SimClock)
    assert laggy.latency >= laggy_dev.latency
    blind = _session(_rig(latency=0.2, queue=4, **kw), frames=2)
    blind.latency = 0.0
    worst_sync, worst_blind = 0.0, 0.0
    for k, p in enumerate(_patterns()):
        want = ideal.take(p, f"p{k}")[0].astype(np.float64) / 65535
        got = laggy.take(p, f"p{k}")[0].astype(np.float64) / 65535
        stale = blind.take(p, f"p{k}")[0].astype(np.float64) / 65535
        worst_sync = max(worst_sync, _halves(got, want))
        worst_blind = max(worst_blind, _halves(stale, want))
    assert worst_sync < 0.01  # noise only
    assert worst_blind > 0.1  # frames of the previous pattern
    assert laggy.reader.dropped > 0


def test_automatic_modes_that_stay_on_are_an_error_unless_allowed() -> None:
    dev = _rig(lockable=False)
    with pytest.raises(DeviceError, match=r"simulated camera: automatic exposure .*--allow-auto"):
        lock_controls(dev.camera)
    warnings = lock_controls(dev.camera, allow_auto=True)
    assert any("automatic white balance" in w for w in warnings)
    dev = _rig()
    dev.camera.set("gain", 3.0)
    assert lock_controls(dev.camera) == []
    assert dev.camera.get("auto_exposure") == 0 and dev.camera.get("gain") == 1.0


@pytest.mark.parametrize(("start", "unit"), [(3.0, 1.0), (0.05, 1.0), (0.1, 5.0)])
def test_exposure_search_puts_white_just_below_clipping(start: float, unit: float) -> None:
    """From a clipping, a dark and a too-dim-for-the-longest-exposure start (the last needs
    gain): the brightest codes end near 80 % of full scale."""
    dev = _rig(exposure=start, unit_exposure=unit, refresh_hz=60.0)
    s = _session(dev)
    s.latency = 0.1
    exposure, gain = search_exposure(dev.camera, dev.projector, s.reader, 0.1, lambda _: None)
    assert dev.camera.get("exposure") == exposure and dev.camera.get("gain") == gain
    w, h = SIZE
    t = dev.projector.show(np.full((h, w, 3), 255, np.uint8))
    level = bright_level(s.reader.fresh(t + 0.1, exposure, gain))
    assert abs(level - TARGET) < 0.08
    if unit > 2:
        assert gain > 1.5 and exposure == pytest.approx(2.0)
    else:
        assert gain == 1.0 and round(exposure * 60, 6) == round(exposure * 60)  # whole periods


def test_exposure_search_refuses_what_clips_at_the_shortest_exposure() -> None:
    dev = _rig(exposure=80.0, unit_exposure=1e-5)  # 0.1 ms (the shortest) already saturates
    s = _session(dev)
    with pytest.raises(DeviceError, match=r"clips even at the shortest exposure.*ND filter"):
        search_exposure(dev.camera, dev.projector, s.reader, 0.1, lambda _: None)


def test_failed_reads_are_retried_and_a_dead_camera_stops_the_capture(tmp_path: Path) -> None:
    dev = _rig(fail_reads=(3, 5, 6))  # the 6th and 7th in a row
    s = _session(dev)
    s.latency = 0.1
    for k, p in enumerate(_patterns()):
        s.take(p, f"p{k}")
    assert s.reader.failed == 3
    dev = _rig(dead_after=40)
    with pytest.raises(DeviceError, match=r"simulated camera: .*gone"):
        run_capture(
            tmp_path / "caps", dev.projector, dev.camera, rig_template=written_rig(dev.sim.rig),
            prompt=lambda stage, msg: True, log=lambda _: None, frames=1, clock=dev.clock,
        )  # fmt: skip
    assert not (tmp_path / "caps").exists()


def test_hdr_bracket_takes_whole_refresh_periods_and_leaves_out_what_cannot(
) -> None:  # fmt: skip
    dev = _rig(exposure=4.0, refresh_hz=60.0)
    s = _session(dev)
    s.latency = 0.1
    lines: list[str] = []
    asked: list[tuple[str, float]] = []
    cam = dev.camera
    set_control = cam.set

    def spy(control: str, value: float) -> float:
        got = set_control(control, value)
        asked.append((control, got))
        return got

    cam.set = spy  # type: ignore[method-assign]
    bracket = Bracket(
        cam, s.reader, dev.clock, DEFAULT_STOPS, parse_response("srgb"), lines.append, 60.0
    )
    w, h = SIZE
    t = dev.projector.show(np.full((h, w, 3), 128, np.uint8))
    merged, _ = bracket.grab(1, t + 0.1)
    assert lines[0].startswith("HDR bracket: relative exposures 1, 1/4, 1/16, 1/64 of 4 s")
    assert "left out 1/256" in lines[1] and "refresh period" in lines[1]
    for control, got in asked:
        if control == "exposure":
            assert abs(got * 60 - round(got * 60)) < 1e-6, got
    assert ("gain", pytest.approx(1.25)) in [(c, v) for c, v in asked if c == "gain"]
    assert merged.dtype == np.float32
    assert cam.get("exposure") == 4.0 and cam.get("gain") == 1.0  # the base, restored


def test_hdr_response_is_estimated_from_the_bracket() -> None:
    dev = _rig(response=2.2, exposure=4.0)
    s = _session(dev)
    found = s.prepare(False, DEFAULT_STOPS, parse_response("srgb"), True)
    assert found is not None and found.kind == "gamma" and abs(found.gamma - 2.2) < 0.2
    assert s.bracket is not None and s.bracket.response == found


def test_hdr_response_estimate_fails_clearly_on_a_flat_scene(monkeypatch) -> None:
    dev = _rig(exposure=4.0)
    s = _session(dev)

    def flat(frames, exposures):
        raise ValueError("no usable samples")

    monkeypatch.setattr(session_mod, "debevec_curve", flat)
    with pytest.raises(DeviceError, match=r"could not be estimated.*--response"):
        s.prepare(False, DEFAULT_STOPS, parse_response("srgb"), True)


def test_a_mono_camera_captures_three_equal_channels(tmp_path: Path) -> None:
    dev = _rig(channels=1)
    lines: list[str] = []

    def prompt(stage: str, message: str) -> bool:
        dev.use_screen(stage)
        return True

    run_capture(
        tmp_path / "caps", dev.projector, dev.camera, rig_template=written_rig(dev.sim.rig),
        prompt=prompt, log=lines.append, frames=2, clock=dev.clock,
    )  # fmt: skip
    assert any("is mono" in line and "not colour" in line for line in lines)
    cs = read_capture_set(tmp_path / "caps")
    images = [cs.white[n] for n in ("gray", "red", "blue")] + [cs.screen["green"]]
    assert is_mono_set(images)
    assert load_rig(tmp_path / "caps" / "rig.toml").capture.space == "camera"
    assert "red_alone" in cs.white and "ramp_blue" in cs.screen
    # calibrate fits it in the per-primary basis: the primaries do not mix there
    cal = calibrate(cs)
    wt = cal.pixel.white.W / np.diagonal(cal.pixel.white.W, axis1=2, axis2=3)[..., None, :]
    off = wt[..., ~np.eye(3, dtype=bool)]
    assert float(np.abs(off).max()) < 1e-6
    assert cal.info["mono"]["additivity_white"] < 0.05
    # a mono set without the primaries alone is refused, saying what to do
    for sub in (cs.white, cs.screen):
        for n in list(sub):
            if n.endswith("_alone") or n.startswith("ramp_"):
                del sub[n]
    with pytest.raises(FitError, match=r"white/red.*mono camera.*primary shown alone"):
        calibrate(cs)


def test_capture_log_has_the_time_left(tmp_path: Path) -> None:
    dev = _rig()
    lines: list[str] = []

    def prompt(stage: str, message: str) -> bool:
        dev.use_screen(stage)
        return True

    run_capture(
        tmp_path / "caps", dev.projector, dev.camera, rig_template=written_rig(dev.sim.rig),
        prompt=prompt, log=lines.append, frames=1, clock=dev.clock, exposure="auto",
    )  # fmt: skip
    assert any(line.startswith("exposure search:") for line in lines)
    assert any("projector -> camera latency" in line for line in lines)
    steps = [line for line in lines if line.startswith("white/gray (")]
    assert steps and "left)" in steps[0]
