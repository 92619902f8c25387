"""HDR captures: the exposure merge (viewcomp.calib.io.hdr), the simulated camera's bracket,
`simulate --hdr` and `simulate --exposure auto` on measured materials, and `capture --hdr`
(the simulated rig end to end, an OpenCV camera over a fake driver)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from unittest import mock

import cv2
import numpy as np
import pytest

from tests.support.calibrations import small_simulator
from viewcomp.calib.fit.calibrate import calibrate
from viewcomp.calib.hw.bracket import Bracket
from viewcomp.calib.hw.clock import MonotonicClock
from viewcomp.calib.hw.interface import DeviceError
from viewcomp.calib.hw.opencv_camera import OpenCVCamera, exposure_value, relative_exposure
from viewcomp.calib.hw.reader import FrameReader
from viewcomp.calib.io.captureset import read_capture_set
from viewcomp.calib.io.hdr import CLIP_CODE, DEFAULT_STOPS, merge_exposures
from viewcomp.calib.io.patterns import table1_patterns
from viewcomp.calib.sim.simulator import CameraPhysics, SimulatorError, white_screen
from viewcomp.calib.world.response import parse_response
from viewcomp.cli import main

SRGB = parse_response("srgb")


def bracket(linear: np.ndarray, stops: tuple[float, ...], seed: int = 0) -> list[np.ndarray]:
    """8-bit sRGB frames of ``linear`` at each relative exposure, with read noise 0.001."""
    rng = np.random.default_rng(seed)
    frames = []
    for s in stops:
        lin = linear * s + rng.standard_normal(linear.shape) * 0.001
        enc = SRGB.encode(np.clip(lin, 0.0, 1.0).astype(np.float32))
        frames.append(np.rint(enc * 255).astype(np.uint8))
    return frames


def test_merge_recovers_diffuse_and_a_highlight_500_times_brighter() -> None:
    diffuse = 0.3
    linear = np.full((40, 60, 3), diffuse)
    linear[15:25, 20:30] = 500 * diffuse  # the highlight: 150 times full scale
    linear[30:, :, 2] = 0.05  # a dim channel
    merged, clipped = merge_exposures(bracket(linear, DEFAULT_STOPS), DEFAULT_STOPS, SRGB)
    assert merged.dtype == np.float32 and merged.shape == linear.shape
    assert not clipped.any()
    assert np.all(np.isfinite(merged))
    np.testing.assert_allclose(merged[15:25, 20:30], 500 * diffuse, rtol=0.02)
    np.testing.assert_allclose(merged[:10].mean(axis=(0, 1)), diffuse, rtol=0.02)
    np.testing.assert_allclose(merged[30:, :, 2].mean(), 0.05, rtol=0.02)
    # one 8-bit frame clips the highlight at full scale: the merge is what holds it
    single, single_clipped = merge_exposures(bracket(linear, (1.0,)), (1.0,), SRGB)
    assert single_clipped[15:25, 20:30].all() and single.max() <= 1.0


def test_clipped_everywhere_keeps_the_shortest_exposure_flagged() -> None:
    linear = np.full((4, 4, 3), 0.5)
    linear[0, 0] = 1e4  # beyond the shortest frame's full scale
    stops = (1.0, 0.25)
    merged, clipped = merge_exposures(bracket(linear, stops), stops, SRGB)
    assert clipped[0, 0].all() and clipped.sum() == 3
    np.testing.assert_allclose(merged[0, 0], 1.0 / 0.25)  # full scale of the 1/4 frame
    np.testing.assert_allclose(merged[1:, 1:], 0.5, rtol=0.02)


def test_black_everywhere_takes_the_longest_exposure() -> None:
    frames = [np.zeros((2, 3, 3), np.uint8), np.full((2, 3, 3), 1, np.uint8)]
    merged, clipped = merge_exposures(frames, (0.5, 1.0), SRGB)
    assert not clipped.any()
    np.testing.assert_allclose(merged, SRGB.decode(np.float32(1 / 255)), rtol=1e-6)


def test_merge_refuses_bad_input() -> None:
    f = np.zeros((2, 3, 3), np.uint8)
    with pytest.raises(ValueError, match="1 frame"):
        merge_exposures([f], (1.0, 0.5), SRGB)
    with pytest.raises(ValueError, match="> 0"):
        merge_exposures([f, f], (1.0, 0.0), SRGB)
    with pytest.raises(ValueError, match="differ"):
        merge_exposures([f, f], (1.0, 1.0), SRGB)
    with pytest.raises(ValueError, match="uint8 or uint16"):
        merge_exposures([f.astype(np.float32)], (1.0,), SRGB)
    with pytest.raises(ValueError, match="frame 1"):
        merge_exposures([f, f.astype(np.uint16)], (1.0, 0.5), SRGB)
    with pytest.raises(SimulatorError, match="hdr_stops"):
        CameraPhysics(hdr_stops=())


def test_simulated_camera_brackets_and_merges() -> None:
    sim = small_simulator(48, 24)
    hdr = replace(sim, camera=replace(sim.camera, exposure=6.0, hdr_stops=DEFAULT_STOPS))
    ramp = table1_patterns(48, 24)["ramp"]
    truth = hdr.expose(hdr.radiance(white_screen(), ramp, hdr.geometry.camera), vignetting=True)
    assert truth.max() > 3  # a single 8-bit exposure would clip the bright end
    got = hdr.capture(white_screen(), ramp, "ramp")
    assert got.dtype == np.float32
    # within noise: no worse than one 8-bit frame where that frame does not clip, and as
    # close (2% rms) where it would
    one = sim.quantise(sim.noise(truth, "ramp@1")).astype(np.float32) / 255
    one = sim.response.decode(one)
    rel = (got - truth) / truth
    rel_one = (one - truth) / truth
    held = (truth > 0.05) & (truth < 0.9)
    assert np.sqrt(np.mean(rel[held] ** 2)) <= np.sqrt(np.mean(rel_one[held] ** 2))
    assert np.sqrt(np.mean(rel[truth > 1.0] ** 2)) < 0.02
    # deterministic: the same key gives the same noise
    np.testing.assert_array_equal(got, hdr.capture(white_screen(), ramp, "ramp"))


def test_simulate_material_hdr_writes_an_unclipped_highlight(
    materials_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "cs"
    material = materials_dir / "red-specular-plastic.npz"
    assert (
        main(["simulate", str(out), "--material", str(material), "--hdr", "--size", "160x80"]) == 0
    )
    assert "exposure auto" in capsys.readouterr().out
    assert (out / "screen" / "gray.npy").is_file() and (out / "white" / "ramp.npy").is_file()
    cs = read_capture_set(out)
    white = cs.white["gray"]
    np.testing.assert_allclose(np.median(white), 0.5, rtol=0.05)  # the diffuse level
    gray = cs.screen["gray"]
    # the highlight, above a single exposure's full scale, is held; far above the diffuse
    assert gray.max() > 2.0
    assert np.all(gray.max(axis=(0, 1)) > 20 * np.median(gray, axis=(0, 1)))
    peak = np.unravel_index(np.argmax(gray[..., 1]), gray.shape[:2])
    assert gray[peak][1] < CLIP_CODE / DEFAULT_STOPS[-1]  # not clipped in the shortest frame


def test_simulate_exposure_auto_leaves_nothing_clipped(
    materials_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "cs"
    material = materials_dir / "green-plastic.npz"
    args = ["simulate", str(out), "--material", str(material), "--exposure", "auto"]
    assert main([*args, "--size", "160x80"]) == 0
    printed = capsys.readouterr().out
    exposure = float(printed.split("exposure auto: ")[1].split()[0])
    assert 0 < exposure < 0.8  # lower than the default: the highlight needs it
    cs = read_capture_set(out)
    for sub in ("white", "screen"):
        for name, img in cs.images(sub).items():
            assert cs.saturated(sub, name) == 0.0, f"{sub}/{name}"
            assert img.max() < 0.99, f"{sub}/{name}"
    assert cs.screen["ramp"].max() > 0.9  # the highlight is what set the exposure
    # the default exposure clips the same scene
    clip = tmp_path / "clip"
    assert main(["simulate", str(clip), "--material", str(material), "--size", "160x80"]) == 0
    assert read_capture_set(clip).saturated("screen", "gray") > 0


def test_simulate_refuses_material_with_screen_and_bad_exposure(tmp_path: Path) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["simulate", str(tmp_path / "a"), "--material", "m.npz", "--screen", "red"])
    assert exc.value.code == 2
    with pytest.raises(SystemExit) as exc:
        main(["simulate", str(tmp_path / "a"), "--exposure", "bright"])
    assert exc.value.code == 2
    assert main(["simulate", str(tmp_path / "a"), "--material", str(tmp_path / "no.npz")]) == 2


def test_simulate_camera_space_material_hdr(materials_dir: Path, tmp_path: Path) -> None:
    out = tmp_path / "cs"
    material = materials_dir / "bluebook.npz"
    args = ["simulate", str(out), "--material", str(material), "--hdr", "--space", "camera"]
    assert main([*args, "--size", "96x48"]) == 0
    cs = read_capture_set(out)
    assert cs.rig.capture.space == "camera"
    assert cs.screen["gray"].dtype == np.float32 and cs.screen["gray"].max() > 1.0
    assert (out / "screen" / "graycode_00.npy").is_file()


# -- capture --hdr ------------------------------------------------------------------------


@pytest.mark.slow
def test_capture_simulate_hdr_end_to_end(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "caps"
    args = ["capture", str(out), "--simulate", "--yes", "--sim-size", "160x80", "--frames", "2"]
    assert main([*args, "--hdr", "--exposure", "4"]) == 0  # 5x the default: the ramp clips
    err = capsys.readouterr().err
    assert "HDR bracket: relative exposures 1, 1/4, 1/16, 1/64, 1/256 of 4" in err
    assert (out / "screen" / "gray.npy").is_file() and (
        out / "screen" / "graycode_00.npy"
    ).is_file()
    assert not (out / "screen" / "gray.png").exists()
    cs = read_capture_set(out)
    assert cs.screen["gray"].dtype == np.float32
    assert cs.white["ramp"].max() > 1.5  # light a single exposure would clip
    cal = calibrate(cs)
    assert cal.pixel is not None


class ExposureCapture:
    """cv2.VideoCapture stand-in with an exposure control: ``accepts`` False refuses to set
    it, ``moves`` False accepts and ignores it (reports the old value)."""

    def __init__(self, accepts: bool, moves: bool) -> None:
        self.accepts, self.moves, self.exposure, self.frames = accepts, moves, 156.0, 0

    def isOpened(self) -> bool:
        return True

    def set(self, prop: int, value: float) -> bool:
        if prop == cv2.CAP_PROP_EXPOSURE:
            if self.accepts and self.moves:
                self.exposure = float(max(1, round(value)))  # V4L2: whole 100 us steps
            return self.accepts
        return True

    def get(self, prop: int) -> float:
        return self.exposure if prop == cv2.CAP_PROP_EXPOSURE else 0.0

    def read(self) -> tuple[bool, np.ndarray]:
        self.frames += 1
        level = min(255, round(self.exposure))
        return True, np.full((4, 6, 3), level, np.uint8)

    def release(self) -> None:
        return None


def _opencv_camera(monkeypatch: pytest.MonkeyPatch, accepts: bool, moves: bool) -> OpenCVCamera:
    fake = ExposureCapture(accepts, moves)
    monkeypatch.setattr(cv2, "VideoCapture", lambda index: fake)
    return OpenCVCamera(0)


def _bracket(cam: OpenCVCamera, response, log) -> Bracket:
    clock = MonotonicClock()
    return Bracket(cam, FrameReader(cam, clock, log), clock, DEFAULT_STOPS, response, log)


def test_opencv_bracket_reads_back_what_the_camera_reports(monkeypatch: pytest.MonkeyPatch) -> None:
    cam = _opencv_camera(monkeypatch, accepts=True, moves=True)
    lines: list[str] = []
    bracket = _bracket(cam, parse_response("linear"), lines.append)
    lin, clipped = bracket.grab(1, 0.0)
    # 156 * 1/256 rounds to 1: the merge uses what the camera reports (1/156, not 1/256)
    assert "1/156" in lines[0] and "1/4" in lines[0]
    assert cam.get("exposure") == 156.0 * 1e-4  # the base is restored (100 us units)
    assert lin.dtype == np.float32 and not clipped.any()


def test_hdr_refuses_a_camera_whose_exposure_cannot_be_set(monkeypatch: pytest.MonkeyPatch) -> None:
    cam = _opencv_camera(monkeypatch, accepts=False, moves=False)
    with pytest.raises(DeviceError, match=r"camera 0.*--hdr"):
        _bracket(cam, SRGB, print).grab(1, 0.0)
    cam = _opencv_camera(monkeypatch, accepts=True, moves=False)
    with pytest.raises(DeviceError, match=r"does not change its exposure.*--hdr"):
        _bracket(cam, SRGB, print).grab(1, 0.0)


def test_exposure_units_linear_and_log2() -> None:
    for base in (156.0, -6.0):
        for rel in DEFAULT_STOPS:
            v = exposure_value(base, rel)
            assert relative_exposure(base, v) == pytest.approx(rel)
    assert exposure_value(-6.0, 0.25) == -8.0 and exposure_value(100.0, 0.25) == 25.0


def test_capture_hdr_without_a_response_estimates_it_from_the_bracket(tmp_path: Path) -> None:
    """`capture --hdr` on hardware without --response or --rig no longer stops: the response
    is estimated from a bracket (tests/calib/hw/test_procedure_devices.py); here the CLI gets past
    the options and fails only at the camera, with exit 2."""
    args = ["capture", str(tmp_path / "c"), "--camera", "7", "--monitor", "0", "--hdr", "--yes"]
    with mock.patch.object(cv2, "VideoCapture", lambda index: ExposureCapture(True, True)):
        with mock.patch(
            "viewcomp.rt.play.projector.GlfwProjector", side_effect=DeviceError("no display")
        ):
            assert main(args) == 2
