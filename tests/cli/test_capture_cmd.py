"""`viewcomp capture`: the procedure over the simulated rig (end to end, refusals, prompts),
the OpenCV camera over a fake driver, and the glfw projector on Xvfb."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path
from unittest import mock

import cv2
import numpy as np
import pytest

from viewcomp.calib.fit.calibrate import Calibration
from viewcomp.calib.fit.colourguide import GUIDE_RADIUS_PX
from viewcomp.calib.hw.camlock import lock_controls
from viewcomp.calib.hw.frames import average_frames
from viewcomp.calib.hw.interface import DeviceError, Frame
from viewcomp.calib.hw.opencv_camera import OpenCVCamera
from viewcomp.calib.hw.plan import capture_plan
from viewcomp.calib.hw.procedure import console_prompt, run_capture
from viewcomp.calib.hw.simrig import SimulatedRig
from viewcomp.calib.io.captureset import read_capture_set
from viewcomp.calib.io.imageio import CaptureError
from viewcomp.calib.sim.simcamera import scaled_camera_rig, written_rig
from viewcomp.calib.sim.simulator import (
    CameraPhysics,
    Simulator,
    make_screen,
    simulation_rig,
    white_screen,
)
from viewcomp.calib.world.rig import load_rig
from viewcomp.cli import main

SIZE = (160, 80)


def _sim_rig(**camera: float) -> SimulatedRig:
    rig = simulation_rig()
    rig = scaled_camera_rig(replace(rig, projector=replace(rig.projector, resolution=SIZE)), SIZE)
    sim = Simulator(rig=rig, seed=3, camera=CameraPhysics(**camera))
    screen = make_screen("green", "glossy", shape=sim.shape)
    return SimulatedRig(sim, {"white": white_screen(), "screen": screen})


class Prompts:
    """Answers prompts and swaps the simulated screen, as the user would."""

    def __init__(self, dev: SimulatedRig, answer: bool = True) -> None:
        self.dev, self.answer, self.stages = dev, answer, []

    def __call__(self, stage: str, message: str) -> bool:
        self.stages.append(stage)
        assert message
        if self.answer:
            self.dev.use_screen(stage)
        return self.answer


def _run(dev: SimulatedRig, out: Path, prompt=None, frames: int = 2) -> list[Path]:
    return run_capture(
        out,
        dev.projector,
        dev.camera,
        rig_template=written_rig(dev.sim.rig),
        prompt=prompt or Prompts(dev),
        log=lambda _: None,
        frames=frames,
        settle=0.0,
        clock=dev.clock,
    )


def test_capture_and_calibrate_end_to_end_through_the_cli(tmp_path: Path, capsys) -> None:
    out = tmp_path / "caps"
    args = ["capture", str(out), "--simulate", "--yes", "--sim-size", "160x80", "--frames", "2"]
    assert main(args) == 0
    assert "camera-space capture set" in capsys.readouterr().out
    cs = read_capture_set(out)
    assert cs.rig.capture.space == "camera" and cs.rig.projector.resolution == SIZE
    assert {p.stem for p in cs.extra["screen"]} >= {"chessboard", "graycode_white", "graycode_00"}
    bundle = tmp_path / "cal.vcb"
    assert main(["calibrate", str(out), "-o", str(bundle)]) == 0
    cal = Calibration.load(bundle)
    geo = cal.info["geometry"]
    assert geo["chessboard"]["zhang_rms_px"] < 0.5 and geo["map"]["chessboard_rms_px"] < 0.5
    assert cal.shape == (SIZE[1], SIZE[0])
    # a camera's set: the colour mixing guided by the screen's colour unless told otherwise
    assert cal.info["colour_guide_px"] == GUIDE_RADIUS_PX
    assert main(["calibrate", str(out), "-o", str(bundle), "--colour-guide-px", "0"]) == 0
    assert Calibration.load(bundle).info["colour_guide_px"] == 0


def test_procedure_prompts_for_each_screen_and_writes_the_plan(tmp_path: Path) -> None:
    dev = _sim_rig()
    prompts = Prompts(dev)
    paths = _run(dev, tmp_path / "caps", prompts)
    assert prompts.stages == ["white", "screen"]
    written = {p.relative_to(tmp_path / "caps").as_posix() for p in paths}
    plan = {f"{s.sub}/{s.name}.png" for s in capture_plan(*SIZE) if not s.check_only}
    assert plan | {"rig.toml"} == written
    rig = load_rig(tmp_path / "caps" / "rig.toml")
    assert rig.capture.space == "camera" and rig.camera.resolution == (320, 180)
    # the white set was captured on the white screen, the real one on the green screen
    cs = read_capture_set(tmp_path / "caps")
    w, s = cs.white["gray"], cs.screen["gray"]
    assert s[..., 1].mean() / s[..., 0].mean() > 1.5 * w[..., 1].mean() / w[..., 0].mean()


def test_stopping_at_a_prompt_writes_nothing(tmp_path: Path) -> None:
    dev = _sim_rig()
    with pytest.raises(CaptureError, match="stopped by the user"):
        _run(dev, tmp_path / "caps", Prompts(dev, answer=False))
    assert not (tmp_path / "caps").exists()


def test_a_camera_moved_during_the_capture_is_refused(tmp_path: Path) -> None:
    dev = _sim_rig()
    dev.move_camera_during("screen", 2, (0.004, 0.0, 0.0))  # bumped tripod, 4 mm, during screen/
    with pytest.raises(CaptureError, match=r"screen/\w+: .*camera moved"):
        _run(dev, tmp_path / "caps")
    assert not (tmp_path / "caps").exists()


def test_saturated_captures_are_refused(tmp_path: Path) -> None:
    dev = _sim_rig(exposure=3.0)
    with pytest.raises(CaptureError, match=r"white/\w+: .*saturated.*lower the camera's exposure"):
        _run(dev, tmp_path / "caps")
    assert not (tmp_path / "caps").exists()


def test_too_dark_is_refused(tmp_path: Path) -> None:
    dev = _sim_rig(exposure=0.05)
    with pytest.raises(CaptureError, match=r"white/gray: .*(too dark|not visible)"):
        _run(dev, tmp_path / "caps")


def test_a_projector_the_camera_cannot_see_is_refused(tmp_path: Path) -> None:
    dev = _sim_rig()
    dev.projector_visible = False
    with pytest.raises(CaptureError, match=r"white/gray: the projected image is not visible"):
        _run(dev, tmp_path / "caps")


def test_a_folder_that_is_not_a_capture_set_is_refused_before_capturing(tmp_path: Path) -> None:
    (tmp_path / "caps").mkdir()
    (tmp_path / "caps" / "notes.txt").write_text("mine")
    dev = _sim_rig()
    with pytest.raises(CaptureError, match="not empty"):
        _run(dev, tmp_path / "caps")
    assert dev.camera._rig._grabs == 0


def test_without_a_rig_the_rig_toml_is_to_complete(tmp_path: Path) -> None:
    dev = _sim_rig()
    run_capture(
        tmp_path / "caps",
        dev.projector,
        dev.camera,
        rig_template=None,
        prompt=Prompts(dev),
        log=lambda _: None,
        frames=1,
        settle=0.0,
        clock=dev.clock,
    )
    text = (tmp_path / "caps" / "rig.toml").read_text()
    assert text.startswith("# TO COMPLETE") and "[tracker] is a guess too" in text
    rig = load_rig(tmp_path / "caps" / "rig.toml")
    assert rig.projector.resolution == SIZE and rig.capture.space == "camera"
    # a webcam above the picture, facing the audience, so `viewcomp track` runs on the set
    assert rig.tracker is not None and rig.tracker.resolution == (1280, 720)
    assert rig.tracker.pose()[0][2, 2] > 0.9 and rig.tracker.position[1] > 0.05


def test_a_template_without_tracker_gets_one_and_one_with_keeps_it() -> None:
    from viewcomp.calib.hw.procedure import capture_rig
    from viewcomp.calib.world.rig import Device

    base = replace(simulation_rig(), tracker=None)
    rig, incomplete = capture_rig(base, SIZE, (320, 180))
    assert not incomplete and rig.tracker is not None and rig.tracker.pose()[0][2, 2] > 0.9
    own = Device(resolution=(640, 480), position=(0.3, 0.4, 0.02), look_at=(0.0, 0.0, 2.0),
                 up=(0.0, 1.0, 0.0), fov_y=40.0)  # fmt: skip
    assert capture_rig(replace(base, tracker=own), SIZE, (320, 180))[0].tracker == own


def test_cli_usage_errors(capsys) -> None:
    with pytest.raises(SystemExit) as e:
        main(["capture", "somewhere"])
    assert e.value.code == 2
    assert "--camera N and --monitor M" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["capture", "--simulate"])
    assert "OUT_DIR" in capsys.readouterr().err


def test_without_a_terminal_or_yes_capture_says_what_it_needs(tmp_path: Path) -> None:
    """No one can confirm the screen changes: said before any device opens, not "stopped by
    the user"; and a prompt whose input ends says the same."""
    out = tmp_path / "caps"
    r = subprocess.run([sys.executable, "-m", "viewcomp", "capture", str(out), "--simulate",
                        "--sim-size", "160x80"], stdin=subprocess.DEVNULL, capture_output=True,
                       text=True, timeout=120)  # fmt: skip
    assert r.returncode == 2
    assert "not a terminal" in r.stderr and "--yes" in r.stderr
    assert "stopped by the user" not in r.stderr and "Traceback" not in r.stderr
    assert not out.exists()
    dev = _sim_rig()
    with mock.patch("builtins.input", side_effect=EOFError):
        with pytest.raises(CaptureError, match=r"ended before an answer.*--yes"):
            _run(dev, out, console_prompt)
    assert not out.exists()


# -- the OpenCV camera over a fake driver ---------------------------------------------------


class FakeCapture:
    """cv2.VideoCapture stand-in: accepts manual exposure (V4L2's 1), refuses to lock white
    balance, has no autofocus control; frames count up."""

    def __init__(self, index: int) -> None:
        self.index = index
        self.props = {cv2.CAP_PROP_AUTO_EXPOSURE: 3.0, cv2.CAP_PROP_WB_TEMPERATURE: 4600.0}
        self.n = 0
        self.released = False

    def isOpened(self) -> bool:
        return self.index == 0

    def set(self, prop: int, value: float) -> bool:
        if prop == cv2.CAP_PROP_AUTO_EXPOSURE and value != 1.0:
            return False
        if prop in (cv2.CAP_PROP_AUTO_WB, cv2.CAP_PROP_AUTOFOCUS):
            return False
        self.props[prop] = value
        return True

    def get(self, prop: int) -> float:
        return self.props.get(prop, 0.0)

    def read(self) -> tuple[bool, np.ndarray]:
        self.n += 1
        frame = np.zeros((4, 6, 3), np.uint8)
        frame[..., 0] = 10 * self.n  # blue in OpenCV's BGR
        frame[..., 2] = 200
        return True, frame

    def release(self) -> None:
        self.released = True


def test_opencv_camera_locks_what_it_can_and_averages(monkeypatch) -> None:
    monkeypatch.setattr(cv2, "VideoCapture", FakeCapture)
    cam = OpenCVCamera(0)
    assert cam.resolution == (6, 4)
    problems = lock_controls(cam, allow_auto=True)
    text = " ".join(problems)
    assert "white balance" in text and "autofocus" in text and "exposure" not in text
    cam.grab(), cam.grab()
    img = average_frames([cam.grab() for _ in range(3)])  # 1 (opening), 2, 3 dropped; 4, 5, 6
    assert img.dtype == np.uint16 and img.shape == (4, 6, 3)
    assert np.all(img[..., 0] == 200 * 257)  # red, from BGR's last channel
    assert np.all(img[..., 2] == 50 * 257)  # blue: mean of 40, 50, 60
    cam.close()
    assert cam._cap.released


def test_opencv_camera_that_cannot_open_says_so(monkeypatch) -> None:
    monkeypatch.setattr(cv2, "VideoCapture", FakeCapture)
    with pytest.raises(DeviceError, match="cannot open camera 3"):
        OpenCVCamera(3)


def _frame(image: np.ndarray) -> Frame:
    return Frame(image=image, timestamp=0.0, exposure=0.01, gain=1.0, sequence=0)


def test_average_frames() -> None:
    a = _frame(np.full((2, 2, 3), 10, np.uint8))
    b = _frame(np.full((2, 2, 3), 11, np.uint8))
    assert average_frames([a]).dtype == np.uint8
    avg = average_frames([a, b])
    assert avg.dtype == np.uint16 and np.all(avg == round(10.5 * 257))
    with pytest.raises(DeviceError, match="changed its frame size"):
        average_frames([a, _frame(np.zeros((3, 2, 3), np.uint8))])


# -- the glfw projector on a virtual X server ---------------------------------------------


@pytest.fixture(scope="module")
def xvfb() -> Iterator[str]:
    exe = shutil.which("Xvfb")
    if exe is None:
        pytest.skip("Xvfb is not installed")
    read, write = os.pipe()
    proc = subprocess.Popen(
        [exe, "-displayfd", str(write), "-screen", "0", "320x200x24", "-nolisten", "tcp"],
        pass_fds=(write,),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    os.close(write)
    with os.fdopen(read) as f:
        number = f.readline().strip()
    if not number:
        proc.kill()
        proc.wait()
        pytest.skip("Xvfb did not start")
    try:
        yield f":{number}"
    finally:
        proc.terminate()
        proc.wait(timeout=10)


_PROJECTOR_SCRIPT = """
import numpy as np
from viewcomp.calib.hw.interface import DeviceError
from viewcomp.rt.play import projector
with projector.GlfwProjector(0) as proj:
    assert proj.resolution == (320, 200), proj.resolution
    rng = np.random.default_rng(0)
    for _ in range(2):
        img = rng.integers(0, 256, (200, 320, 3), dtype=np.uint8)
        t = proj.show(img)
        assert isinstance(t, float) and proj.refresh_hz > 0
        np.testing.assert_array_equal(proj.read_back(), img)
    try:
        proj.show(np.zeros((200, 320, 3), np.float32))
    except ValueError as e:
        assert "uint8" in str(e)
    else:
        raise AssertionError("a float image was shown")
try:
    projector.GlfwProjector(5)
except DeviceError as e:
    assert "no monitor 5" in str(e), e
else:
    raise AssertionError("monitor 5 opened")
print("projector ok")
"""


def test_glfw_projector_shows_patterns_pixel_for_pixel(xvfb: str) -> None:
    # in a fresh process: GLX (glfw) cannot be made current in a process whose thread already
    # holds the EGL context of the `gl` tests (Mesa answers BadAccess and exits)
    env = dict(os.environ, DISPLAY=xvfb)
    done = subprocess.run(
        [sys.executable, "-c", _PROJECTOR_SCRIPT],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    assert "projector ok" in done.stdout
    listed = subprocess.run(
        [sys.executable, "-m", "viewcomp", "capture", "--list-monitors"],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert listed.returncode == 0, listed.stderr
    assert "320x200" in listed.stdout


def test_the_response_can_be_estimated_at_capture(tmp_path: Path) -> None:
    dev = _sim_rig()
    rig = replace(dev.sim.rig, camera=replace(dev.sim.rig.camera, response=2.2))
    dev = SimulatedRig(dev.sim.with_rig(rig), dev.screens)
    template = replace(written_rig(rig), camera=replace(rig.camera, response="linear"))
    run_capture(
        tmp_path / "caps",
        dev.projector,
        dev.camera,
        rig_template=template,
        prompt=Prompts(dev),
        log=lambda _: None,
        frames=2,
        settle=0.0,
        clock=dev.clock,
        response="estimate",
    )
    found = load_rig(tmp_path / "caps" / "rig.toml").camera.response
    assert isinstance(found, float) and abs(found - 2.2) < 0.1
