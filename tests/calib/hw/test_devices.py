"""The device layer of `viewcomp capture` without hardware: the plug-in loader, the optional
backends' missing-package errors and unit conversions, the OpenCV camera's exposure units and
timestamps over a fake driver, frame averaging, retries, HDR exposure planning, the response
fit and progress."""

from __future__ import annotations

import sys
import textwrap
from pathlib import Path

import cv2
import numpy as np
import pytest

from viewcomp.calib.hw.backends import open_camera
from viewcomp.calib.hw.bracket import exposure_and_gain
from viewcomp.calib.hw.clock import SimClock
from viewcomp.calib.hw.frames import FRAMES_8BIT, FRAMES_DEEP, average_frames, default_frames
from viewcomp.calib.hw.gphoto2_camera import nearest, parse_iso, parse_shutter
from viewcomp.calib.hw.hdrresponse import (
    choose_response,
    debevec_curve,
    fit_response,
    response_table,
)
from viewcomp.calib.hw.interface import DeviceError, Frame, FrameError
from viewcomp.calib.hw.opencv_camera import OpenCVCamera
from viewcomp.calib.hw.progress import Progress, duration
from viewcomp.calib.hw.reader import FrameReader
from viewcomp.calib.world.response import parse_response
from viewcomp.cli import main

PLUGIN = """
from viewcomp.calib.hw.interface import ControlRange, Frame
import numpy as np

class Cam:
    def __init__(self, spec):
        self.spec = spec
    name = "vendor camera"
    resolution = (4, 2)
    channels = 3
    def controls(self):
        return {"exposure": ControlRange(0.001, 1.0)}
    def get(self, control):
        return 0.01
    def set(self, control, value):
        return value
    def grab(self):
        return Frame(np.zeros((2, 4, 3), np.uint8), 0.0, 0.01, 1.0, 0)
    def close(self):
        pass

def make(spec):
    return Cam(spec)

def broken(spec):
    return object()
"""


@pytest.fixture
def plugin_module(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> str:
    name = "viewcomp_test_vendorcam"
    (tmp_path / f"{name}.py").write_text(textwrap.dedent(PLUGIN))
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, name, raising=False)
    return name


def test_a_plugin_backend_is_loaded_by_module_and_factory(plugin_module: str) -> None:
    cam = open_camera(f"{plugin_module}:make", "serial-42", SimClock())
    assert cam.name == "vendor camera" and cam.spec == "serial-42"  # type: ignore[attr-defined]
    assert cam.grab().image.shape == (2, 4, 3)


def test_plugin_errors_name_what_is_wrong(plugin_module: str) -> None:
    clock = SimClock()
    with pytest.raises(DeviceError, match=r"cannot import 'no_such_vendor_mod'.*PYTHONPATH"):
        open_camera("no_such_vendor_mod:make", "", clock)
    with pytest.raises(DeviceError, match=r"has no function 'nope'"):
        open_camera(f"{plugin_module}:nope", "", clock)
    with pytest.raises(DeviceError, match=r"returned a object without name, .*grab"):
        open_camera(f"{plugin_module}:broken", "", clock)
    with pytest.raises(DeviceError, match=r"unknown --camera-backend 'webcam'.*module:factory"):
        open_camera("webcam", "0", clock)
    with pytest.raises(DeviceError, match=r"takes a camera index"):
        open_camera("opencv", "front", clock)


def test_a_bad_plugin_exits_2_from_the_cli(tmp_path: Path, capsys) -> None:
    args = ["capture", str(tmp_path / "c"), "--camera-backend", "no_such_vendor_mod:make"]
    assert main([*args, "--monitor", "0", "--yes"]) == 2
    err = capsys.readouterr().err
    assert "no_such_vendor_mod" in err and "Traceback" not in err


def test_optional_backends_say_which_package_is_missing(monkeypatch) -> None:
    from viewcomp.calib.hw.genicam_camera import GenICamCamera
    from viewcomp.calib.hw.gphoto2_camera import GPhoto2Camera

    monkeypatch.setitem(sys.modules, "gphoto2", None)
    with pytest.raises(DeviceError, match=r"package 'gphoto2'.*pip install gphoto2"):
        GPhoto2Camera("")
    monkeypatch.setitem(sys.modules, "harvesters", None)
    monkeypatch.setitem(sys.modules, "harvesters.core", None)
    with pytest.raises(DeviceError, match=r"package 'harvesters'.*pip install harvesters"):
        GenICamCamera("producer.cti")


def test_genicam_needs_a_producer_file(tmp_path: Path) -> None:
    pytest.importorskip("harvesters.core")  # optional: the message before it is tested above
    from viewcomp.calib.hw.genicam_camera import GenICamCamera

    with pytest.raises(DeviceError, match=r"no GenTL producer file .*missing\.cti"):
        GenICamCamera(str(tmp_path / "missing.cti"))
    with pytest.raises(DeviceError, match=r"PRODUCER\.cti\[#SERIAL\]"):
        GenICamCamera("camera-1")


def test_gphoto2_choices_to_seconds_and_gain() -> None:
    assert parse_shutter("1/60") == pytest.approx(1 / 60)
    assert parse_shutter("0.5") == 0.5 and parse_shutter('2"') == 2.0
    assert parse_shutter("1/4000s") == pytest.approx(1 / 4000)
    assert parse_shutter("bulb") is None and parse_iso("Auto") is None
    choices = ["1/30", "1/60", "1/125", "bulb"]
    assert nearest(choices, parse_shutter, 1 / 100) == "1/125"
    assert nearest(["Auto", "100", "200", "400"], parse_iso, 300) == "400"  # log scale


class TimedCapture:
    """cv2.VideoCapture stand-in reporting backend ``backend``, exposure ``raw`` in its units,
    frames that never wait (a queue that is always full)."""

    def __init__(self, backend: str, raw: float) -> None:
        self.backend, self.raw, self.n = backend, raw, 0

    def isOpened(self) -> bool:
        return True

    def getBackendName(self) -> str:
        return self.backend

    def set(self, prop: int, value: float) -> bool:
        if prop == cv2.CAP_PROP_EXPOSURE:
            self.raw = float(value)
        return True

    def get(self, prop: int) -> float:
        return {cv2.CAP_PROP_EXPOSURE: self.raw, cv2.CAP_PROP_BUFFERSIZE: 2.0}.get(prop, 0.0)

    def read(self) -> tuple[bool, np.ndarray]:
        self.n += 1
        return True, np.full((2, 3, 3), self.n % 256, np.uint8)

    def release(self) -> None:
        return None


def test_opencv_exposure_units_by_backend(monkeypatch) -> None:
    monkeypatch.setattr(cv2, "VideoCapture", lambda i: TimedCapture("V4L2", 156.0))
    cam = OpenCVCamera(0, clock=SimClock())
    assert "V4L2" in cam.name and cam.get("exposure") == pytest.approx(0.0156)
    assert cam.set("exposure", 0.01) == pytest.approx(0.01)
    assert cam._cap.raw == pytest.approx(100.0)  # 100 us units
    fake = TimedCapture("DSHOW", -6.0)
    monkeypatch.setattr(cv2, "VideoCapture", lambda i: fake)
    cam = OpenCVCamera(0, clock=SimClock())
    assert cam.get("exposure") == pytest.approx(1 / 64)
    cam.set("exposure", 1 / 256)
    assert fake.raw == pytest.approx(-8.0)  # log2 seconds
    monkeypatch.setattr(cv2, "VideoCapture", lambda i: TimedCapture("GSTREAMER", 300.0))
    cam = OpenCVCamera(0, clock=SimClock())
    assert "guessed" in cam.units and cam.get("exposure") == pytest.approx(0.03)


def test_opencv_frames_are_never_taken_as_newer_than_they_are(monkeypatch) -> None:
    """Reads that never wait come from the driver's queue (2 deep here): a frame read at
    clock time t is stamped no later than the start of the read two reads before, minus an
    exposure and a frame period; the first reads, whose age is unknown, as never fresh."""
    monkeypatch.setattr(cv2, "VideoCapture", lambda i: TimedCapture("MSMF", -5.0))
    clock = SimClock(100.0)
    cam = OpenCVCamera(0, clock=clock)  # read 1 (opening)
    calls = []
    for k in range(6):
        clock.sleep(1.0)
        calls.append(clock.now())
        f = cam.grab()
        if k < 1:
            assert f.timestamp == -np.inf
        else:
            assert f.timestamp <= calls[k - 1] - 2.0**-5
    reader = FrameReader(cam, clock, lambda _: None)
    t = clock.now()
    clock.sleep(0.001)
    with pytest.raises(DeviceError, match=r"camera 0 .*delivered \d+ frames, none started"):
        reader.fresh(t)  # the clock never moves: no read is known to be fresh


def _frame(image: np.ndarray, bits: int = 8) -> Frame:
    return Frame(image=image, timestamp=0.0, exposure=0.01, gain=1.0, sequence=0, bits=bits)


def test_average_frames_scales_deep_and_mono_frames() -> None:
    deep = _frame(np.full((2, 2, 3), 4095, np.uint16), bits=12)
    assert np.all(average_frames([deep]) == 65535)
    mono = [_frame(np.full((2, 2), v, np.uint8)) for v in (10, 20)]
    avg = average_frames(mono)
    assert avg.shape == (2, 2, 3) and np.all(avg == 15 * 257)


def test_the_default_frame_count_follows_the_cameras_bit_depth() -> None:
    assert default_frames(_frame(np.zeros((2, 2, 3), np.uint8))) == FRAMES_8BIT == 16
    assert default_frames(_frame(np.zeros((2, 2), np.uint16), bits=12)) == FRAMES_DEEP == 8


@pytest.mark.parametrize(("profile", "want"), [("webcam", FRAMES_8BIT), ("mono12", FRAMES_DEEP)])
def test_a_session_without_frames_takes_the_cameras_default(profile: str, want: int) -> None:
    # the emulated devices, as `capture --emulate` opens them: the count is read from the
    # frames the latency measurement grabbed, and said
    from viewcomp.calib.emu.emulator import open_emulator
    from viewcomp.calib.hw.session import Session

    emu = open_emulator(profile, "magenta", seed=0, projector_size=(64, 32))
    lines: list[str] = []
    reader = FrameReader(emu.camera, emu.clock, lines.append)
    session = Session(emu.projector, emu.camera, emu.clock, reader, lines.append, None, 0.0)
    session.prepare(False, None, parse_response("linear"), False)
    assert session.frames == want
    assert any(f"averaging {want} frames per capture" in line for line in lines)
    given = Session(emu.projector, emu.camera, emu.clock, reader, lines.append, 3, 0.0)
    given.prepare(False, None, parse_response("linear"), False)
    assert given.frames == 3
    emu.close()


def _webcam_tone() -> tuple[np.ndarray, np.ndarray]:
    """The emulated webcam's own tone curve (its truth, not a model viewcomp fits), tabulated:
    (linear light xs, encoded 0..1 ys), so np.interp(code, ys, xs) is its inverse."""
    from viewcomp.calib.emu.camera import tone_curve

    xs = np.linspace(0.0, 1.0, 100001)
    return xs, tone_curve(xs, 0.25).astype(np.float64)


def test_the_table_smooths_away_a_curves_per_code_wiggles() -> None:
    # the emulated webcam's true curve at every code, each code's light off by 2 % at random
    # (Debevec's per-code noise): the table follows the curve, not the wiggles
    xs, ys = _webcam_tone()
    true = np.interp(np.arange(256) / 255.0, ys, xs)
    wiggly = np.maximum(true, 1e-6) * (1.0 + 0.02 * np.random.default_rng(5).standard_normal(256))
    table = response_table(wiggly)
    k = np.arange(32, 225)
    got = table.decode(k / 255.0) / table.decode(np.array([128 / 255.0]))
    rel = got / (true[k] / true[128]) - 1.0
    noisy = wiggly[k] / wiggly[128] / (true[k] / true[128]) - 1.0
    rms = float(np.sqrt(np.mean(rel**2)))
    print(f"\nwiggles {np.sqrt(np.mean(noisy**2)):.4f} RMS, the table {rms:.4f} off the curve")
    assert rms < 0.006 and float(np.sqrt(np.mean(noisy**2))) > 0.015


class Flaky:
    """A camera whose reads follow ``script``: 'ok', 'fail' (FrameError) or 'dead'."""

    name = "flaky camera"

    def __init__(self, script: list[str]) -> None:
        self.script = list(script)

    def grab(self) -> Frame:
        what = self.script.pop(0)
        if what == "fail":
            raise FrameError("USB transfer dropped")
        if what == "dead":
            raise DeviceError("device gone")
        return _frame(np.zeros((1, 1, 3), np.uint8))


def test_failed_reads_are_retried_and_a_dead_camera_is_named() -> None:
    lines: list[str] = []
    reader = FrameReader(Flaky(["fail", "fail", "ok"]), SimClock(), lines.append, retries=2)  # type: ignore[arg-type]
    reader.grab()
    assert reader.failed == 2 and "flaky camera" in lines[0]
    reader = FrameReader(Flaky(["fail"] * 3), SimClock(), lines.append, retries=2)  # type: ignore[arg-type]
    with pytest.raises(DeviceError, match=r"flaky camera: 3 reads in a row failed.*cable"):
        reader.grab()
    reader = FrameReader(Flaky(["fail", "dead"]), SimClock(), lines.append)  # type: ignore[arg-type]
    with pytest.raises(DeviceError, match=r"^flaky camera: device gone"):
        reader.grab()


def test_hdr_exposures_are_whole_refresh_periods() -> None:
    period = 1 / 60
    e, g = exposure_and_gain(0.0625, 60.0, True, 16.0)  # 3.75 periods
    assert e == pytest.approx(3 * period) and g == pytest.approx(1.25)
    assert exposure_and_gain(0.01, 60.0, True, 16.0) is None  # under one period at gain 1
    e, g = exposure_and_gain(0.0625, 60.0, False, 1.0)  # no gain: the nearest whole periods
    assert e == pytest.approx(4 * period) and g == 1.0
    assert exposure_and_gain(0.0625, None, True, 16.0) == (0.0625, 1.0)


def test_the_response_is_recovered_from_a_bracket() -> None:
    rng = np.random.default_rng(1)
    light = np.tile(np.geomspace(0.002, 4.0, 300)[None, :, None], (30, 1, 3))
    stops = [1.0, 1 / 4, 1 / 16, 1 / 64]
    for spec, check in (
        ("srgb", lambda r: r.kind == "srgb"),
        (2.2, lambda r: abs(r.gamma - 2.2) < 0.15),
    ):
        true = parse_response(spec)
        frames = []
        for s in stops:
            lin = np.clip(light * s + rng.normal(0, 0.001, light.shape), 0, 1).astype(np.float32)
            frames.append(np.rint(true.encode(lin) * 255).astype(np.uint8))
        found, misfit = fit_response(debevec_curve(frames, stops))
        assert check(found), (spec, found)
        assert misfit < 0.15
        # the bracket's stops agree no better through Debevec's curve as a table: the model
        chosen, said = choose_response(debevec_curve(frames, stops), frames, stops)
        assert chosen == found and "through the curve as a table" in said


def test_an_s_shaped_camera_curve_is_kept_as_a_table() -> None:
    # the emulated webcam's own tone curve (its truth, not a model viewcomp fits): neither
    # sRGB nor a power law, so the stops agree only through the table, which follows it
    rng = np.random.default_rng(2)
    light = np.tile(np.geomspace(0.002, 4.0, 300)[None, :, None], (30, 1, 3))
    stops = [1.0, 1 / 4, 1 / 16, 1 / 64]
    xs, ys = _webcam_tone()
    frames = []
    for s in stops:
        lin = np.clip(light * s + rng.normal(0, 0.001, light.shape), 0, 1)
        frames.append(np.rint(np.interp(lin, xs, ys) * 255).astype(np.uint8))
    curve = debevec_curve(frames, stops)
    model, _ = fit_response(curve)
    chosen, said = choose_response(curve, frames, stops)
    assert chosen.kind == "table" and chosen == response_table(curve), said
    codes = np.arange(32, 225) / 255.0
    true = np.interp(codes, ys, xs)
    mid = np.interp(128 / 255.0, ys, xs)

    def off(resp: object) -> float:  # worst relative error, both normalised at code 128
        got = resp.decode(codes) / resp.decode(np.array([128 / 255.0]))  # type: ignore[attr-defined]
        return float(np.max(np.abs(got / (true / mid) - 1.0)))

    print(f"\ntable {off(chosen):.3f}, {model.spec!r} {off(model):.3f} off the true curve")
    assert off(chosen) < 0.05 and off(model) > 0.1


def test_progress_says_the_time_left_on_the_clock() -> None:
    clock = SimClock()
    lines: list[str] = []
    p = Progress(4, clock, lines.append)
    for _ in range(2):
        clock.sleep(30.0)
        p.step("white/gray")
    assert lines[-1] == "white/gray (2/4, 1 min 00 s left)"
    assert duration(5) == "5 s" and duration(3725) == "1 h 02 min"
