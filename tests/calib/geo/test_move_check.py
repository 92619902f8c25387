"""The camera-moved check (viewcomp.calib.geo.framematch; the live checks of `capture`, gray
shown again between captures; MoveCheck of `calibrate`): a still camera in front of a glossy
measured material is not refused, a bump of 1.5 camera px is, naming the capture, and a
0.3 px jitter is not.

The shifts are set from the rig's own projection of the projector's frame (the simulator's
geometry), never from the check. Sideways (x) moves: the simulated camera point-samples the
frame's edge, so a sub-pixel vertical move of its horizontal edges is rounded to 0 or 1 px.
"""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest

from tests.support.materials import MEASURED
from viewcomp.calib.errors import FitError
from viewcomp.calib.geo.framematch import MIN_MATCH, frame_edges, frame_shift, lit_region
from viewcomp.calib.geo.rectify import calibrate_geometry, rectify_capture_set
from viewcomp.calib.hw.plan import capture_plan
from viewcomp.calib.hw.procedure import run_capture
from viewcomp.calib.hw.simrig import SimulatedRig
from viewcomp.calib.io.captureset import (
    capture_set_from_raw,
    read_capture_set,
)
from viewcomp.calib.io.hdr import DEFAULT_STOPS
from viewcomp.calib.io.imageio import CaptureError
from viewcomp.calib.sim.simcamera import (
    SimCamera,
    camera_simulator,
    capture_camera_patterns,
    scaled_camera_rig,
    written_rig,
)
from viewcomp.calib.sim.simulator import (
    PROJECTOR_PRESETS,
    AnyScreen,
    make_screen,
    material_screen,
    simulation_rig,
    white_screen,
)
from viewcomp.calib.world.geometry import screen_points_at
from viewcomp.calib.world.rig import Rig
from viewcomp.cli import main

SIZE = (160, 80)  # projector; the camera 320x180. The highlight fooled the old check here too
MATERIALS = MEASURED
GLOSSY = "red-specular-plastic"  # the material of the report: 6.3 px "moved" at 320x160


def _material(materials_dir: Path, name: str) -> Path:
    path = materials_dir / f"{name}.npz"
    if not path.is_file():
        pytest.skip(f"measured material {name}.npz not in {materials_dir}")
    return path


def _rig(size: tuple[int, int] = SIZE) -> Rig:
    rig = simulation_rig()
    rig = replace(rig, projector=replace(rig.projector, resolution=size, principal_point=None))
    return scaled_camera_rig(rig, size)


def _frame_px_per_metre(rig: Rig) -> float:
    """Camera px the projector's frame moves (mean over a grid on it) per metre of sideways
    camera translation, by the rig's projection."""
    w, h = rig.projector.resolution
    uu, vv = np.meshgrid(np.linspace(0, w - 1, 9), np.linspace(0, h - 1, 5))
    pts = screen_points_at(rig.projector, np.stack([uu, vv], -1).reshape(-1, 2))
    d = 1e-3
    c = rig.camera
    moved = replace(
        rig,
        camera=replace(
            c,
            position=(c.position[0] + d, *c.position[1:]),
            look_at=(c.look_at[0] + d, *c.look_at[1:]),
        ),
    )
    shift = moved.camera.project(pts) - rig.camera.project(pts)
    return float(np.mean(np.linalg.norm(shift, axis=1))) / d


def _offset(rig: Rig, px: float) -> tuple[float, float, float]:
    """The sideways camera move (metres) that moves the frame by ``px`` camera px."""
    return (px / _frame_px_per_metre(rig), 0.0, 0.0)


def _screen(kind: str, materials_dir: Path | None, sim_shape: tuple[int, int]) -> AnyScreen:
    if kind == "glossy":
        return make_screen("green", "glossy", shape=sim_shape)
    assert materials_dir is not None
    return material_screen(_material(materials_dir, kind))


def _device(kind: str, materials_dir: Path | None) -> SimulatedRig:
    preset = "default" if kind == "glossy" else "dlp"
    sim = camera_simulator(_rig(), seed=2, projector=PROJECTOR_PRESETS[preset])
    screen = _screen(kind, materials_dir, sim.shape)
    return SimulatedRig(sim, {"white": white_screen(), "screen": screen})


class _Counting:
    """The projector of a simulated rig, counting the patterns shown with each screen in
    place (what :meth:`SimulatedRig.move_camera_during` counts)."""

    def __init__(self, dev: SimulatedRig) -> None:
        self.dev, self.shows = dev, {"white": 0, "screen": 0}

    def __getattr__(self, name: str):
        return getattr(self.dev.projector, name)

    def show(self, image: np.ndarray) -> float:
        self.shows[self.dev.screen_name] += 1
        return self.dev.projector.show(image)


def _capture(dev: SimulatedRig, out: Path, hdr: bool, projector=None, log=None) -> list[Path]:
    def prompt(stage: str, message: str) -> bool:
        dev.use_screen(stage)
        return True

    return run_capture(
        out,
        projector or dev.projector,
        dev.camera,
        rig_template=written_rig(dev.sim.rig),
        prompt=prompt,
        log=log or (lambda _: None),
        frames=2,
        clock=dev.clock,
        response="srgb",
        hdr_stops=DEFAULT_STOPS if hdr else None,
    )


_SHOWS: dict[tuple[str, bool], dict[str, tuple[str, int]]] = {}


def _first_grabs(
    kind: str, materials_dir: Path | None, hdr: bool, tmp: Path
) -> dict[str, tuple[str, int]]:
    """Capture name ("white/red") -> (its screen, the patterns shown with that screen before
    it): what ``move_camera_during`` takes to move the camera at that capture; from a run
    with a still camera (which must pass), one per screen and bracket."""
    if (kind, hdr) in _SHOWS:
        return _SHOWS[(kind, hdr)]
    dev = _device(kind, materials_dir)
    counting = _Counting(dev)
    at: dict[str, tuple[str, int]] = {}

    def log(line: str) -> None:  # logged after each capture: "white/red (3/56, ...)"
        name = line.rsplit(" (", 1)[0]
        sub = name.split("/", 1)[0]
        if sub in counting.shows and "/" in name:  # its own show was the last one
            at.setdefault(name, (sub, counting.shows[sub] - 1))

    _capture(dev, tmp / f"still-{kind}-{hdr}", hdr, counting, log)
    _SHOWS[(kind, hdr)] = at
    return at


# --- the comparison and the plan -------------------------------------------------------------


def _frame_image(dx: float, highlight: str) -> tuple[np.ndarray, np.ndarray]:
    """A (180, 320, 3) capture: a dim lit frame on a dark surround, moved by ``dx`` px (by
    warpAffine: the truth), with a bright highlight of one shape or another at the centre;
    and its clipped pixels."""
    img = np.full((180, 320, 3), 0.001, np.float32)
    img[40:140, 60:260] = 0.05
    y, x = np.mgrid[0:180, 0:320]
    r = np.hypot(x - 160.0, y - 90.0)
    if highlight == "spot":
        img += (1.5 * np.exp(-((r / 3.0) ** 2)))[..., None]
    else:  # a ring, as a pattern dark at the highlight's centre leaves it
        img += (1.5 * np.exp(-(((r - 5.0) / 2.0) ** 2)))[..., None]
    img = cv2.GaussianBlur(img, (0, 0), 0.8)
    m = np.float32([[1, 0, dx], [0, 1, 0]])
    img = cv2.warpAffine(img, m, (320, 180), flags=cv2.INTER_CUBIC)
    img += np.random.default_rng(int(dx * 10)).normal(0, 0.001, img.shape).astype(np.float32)
    clipped = np.any(img >= 1.0, axis=2)
    return np.minimum(img, 1.0), clipped


def _rough(img: np.ndarray, gain: float, seed: int) -> np.ndarray:
    """What a cheap camera makes of ``img``: exposure off by ``gain``, 3 codes of noise, sRGB
    8-bit JPEG at quality 70, back to linear."""
    x = np.clip(img * gain, 0.0, 1.0)
    code = np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055) * 255.0
    code += np.random.default_rng(seed).normal(0.0, 3.0, code.shape)
    ok, buf = cv2.imencode(
        ".jpg", np.clip(np.rint(code), 0, 255).astype(np.uint8), [cv2.IMWRITE_JPEG_QUALITY, 70]
    )
    assert ok
    c = cv2.imdecode(buf, cv2.IMREAD_UNCHANGED).astype(np.float32) / 255.0
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4).astype(np.float32)


@pytest.mark.parametrize("rough", [False, True], ids=["clean", "noise-jpeg-drift"])
def test_a_highlight_that_changes_shape_is_not_a_move_and_a_move_is_measured(rough) -> None:
    def capture(dx: float, highlight: str, gain: float) -> tuple[np.ndarray, np.ndarray]:
        img, clipped = _frame_image(dx, highlight)
        if rough:
            img = _rough(img, gain, int(10 * dx) + len(highlight))
            clipped = np.any(img >= 1.0, axis=2)
        return img, clipped

    ref, ref_clipped = capture(0.0, "spot", 1.0)
    lit = lit_region(ref)
    reference = frame_edges(ref, lit, ref_clipped)
    img, clipped = capture(0.0, "ring", 1.03)
    still = frame_shift(reference, frame_edges(img, lit, clipped))
    assert still.distance < 0.15 and still.match > MIN_MATCH
    img, clipped = capture(1.5, "ring", 0.97)
    moved = frame_shift(reference, frame_edges(img, lit, clipped))
    assert moved.dx == pytest.approx(1.5, abs=0.15) and abs(moved.dy) < 0.15
    img, clipped = capture(0.3, "ring", 1.03)
    jitter = frame_shift(reference, frame_edges(img, lit, clipped))
    assert jitter.dx == pytest.approx(0.3, abs=0.15)


def test_the_plan_shows_gray_again_but_never_between_a_plane_and_its_inverse() -> None:
    plan = capture_plan(*SIZE)
    again = [i for i, s in enumerate(plan) if s.check_only]
    assert again and all(plan[i].name.startswith("gray (again") for i in again)
    gray = next(s.pattern for s in plan if s.name == "gray")
    for i in again:
        assert np.array_equal(plan[i].pattern, gray)
        before, after = plan[i - 1].name, plan[i + 1].name
        assert plan[i + 1].sub == plan[i].sub  # not a stage's last: the procedure shows it then
        if before.startswith("graycode_") and before[9:].isdigit():
            assert int(before[9:]) % 2 == 1, (before, after)
    gaps = np.diff([i for i, s in enumerate(plan) if s.name == "gray" or s.check_only])
    assert gaps.max() <= 8  # every few captures (the white stage's gray is shown at its end)


# --- capture: a still camera passes ------------------------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize("hdr", [False, True], ids=["8bit", "hdr"])
@pytest.mark.parametrize("name", MATERIALS)
def test_capture_of_a_still_camera_passes_on_every_material(
    materials_dir: Path, tmp_path: Path, capsys, name: str, hdr: bool
) -> None:
    material = _material(materials_dir, name)
    args = ["capture", str(tmp_path / "c"), "--simulate", "--material", str(material)]
    # 8 frames a capture (the simulated camera's default is 16): the move check is the subject
    args += ["--sim-size", f"{SIZE[0]}x{SIZE[1]}", "--frames", "8", "--yes"]
    args += ["--hdr"] if hdr else []
    rc = main(args)
    err = capsys.readouterr().err
    assert _no_move_refusal(err), err
    if hdr or rc == 0:
        assert rc == 0, err
    else:  # 8 bits may clip on the highlight: refused for that only, pointing at --hdr
        assert "saturated" in err and "--hdr" in err, err


@pytest.mark.slow
def _no_move_refusal(log: str) -> bool:
    """No camera-moved refusal in a capture's log (the refusals say the frame "moved" or
    "lies" elsewhere, or that it cannot be matched); the log's other lines may speak of
    frames."""
    return not any(w in log for w in ("moved", "lies ", "cannot be matched", "no clear match"))


def test_the_reported_capture_is_not_refused_as_moved(materials_dir: Path, tmp_path, capsys):
    # the report's command: 320x160, 8 bits; "screen/chessboard: the projector's frame moved
    # 6.3 camera px since screen/gray" before
    material = _material(materials_dir, GLOSSY)
    args = ["capture", str(tmp_path / "c"), "--simulate", "--material", str(material)]
    rc = main([*args, "--sim-size", "320x160", "--frames", "8", "--yes"])
    err = capsys.readouterr().err
    assert _no_move_refusal(err), err
    assert rc == 0 or ("saturated" in err and "--hdr" in err), err


# --- calibrate: a still camera passes ----------------------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize("hdr", [False, True], ids=["8bit", "hdr"])
@pytest.mark.parametrize("name", MATERIALS)
def test_calibrate_of_a_still_camera_passes_on_every_material(
    materials_dir: Path, tmp_path: Path, name: str, hdr: bool
) -> None:
    material = _material(materials_dir, name)
    out = tmp_path / "s"
    args = ["simulate", str(out), "--space", "camera", "--material", str(material)]
    assert main([*args, "--size", f"{SIZE[0]}x{SIZE[1]}"] + (["--hdr"] if hdr else [])) == 0
    cs = read_capture_set(out)
    try:
        _, stats = rectify_capture_set(cs)
    except FitError as e:
        # 8 bits may clip the chessboard on a glossy metal: refused for that only
        assert not hdr and "saturated" in str(e), e
        return
    assert stats["max_frame_shift_px"] < 0.3  # the camera did not move at all


@pytest.mark.slow
def test_the_reported_set_calibrates(materials_dir: Path, tmp_path: Path) -> None:
    # before: "graycode_32 ... lies 1.2 camera px from where graycode_white has it"
    material = _material(materials_dir, GLOSSY)
    out = tmp_path / "s"
    args = ["simulate", str(out), "--space", "camera", "--material", str(material)]
    assert main([*args, "--size", "320x160"]) == 0
    _, stats = rectify_capture_set(read_capture_set(out))
    assert stats["max_frame_shift_px"] < 0.3


# --- capture: a bump is refused, naming the capture; a jitter is not -------------------------


BUMPS = [  # (screen, HDR, the capture the camera moves at: early, middle, late)
    ("glossy", False, "white/red"),
    ("glossy", False, "screen/chessboard"),
    ("glossy", False, "screen/graycode_20"),
    (GLOSSY, True, "white/ramp"),
    (GLOSSY, True, "screen/chessboard"),
    (GLOSSY, True, "screen/graycode_14"),
]


@pytest.mark.slow
@pytest.mark.parametrize(("kind", "hdr", "at"), BUMPS)
def test_a_bump_of_one_and_a_half_px_is_refused_naming_the_capture(
    materials_dir: Path, tmp_path_factory, kind: str, hdr: bool, at: str
) -> None:
    mats = None if kind == "glossy" else materials_dir
    grabs = _first_grabs(kind, mats, hdr, tmp_path_factory.mktemp("still"))
    dev = _device(kind, mats)
    dev.move_camera_during(*grabs[at], _offset(dev.sim.rig, 1.5))
    with pytest.raises(CaptureError) as e:
        _capture(dev, tmp_path_factory.mktemp("bumped") / "c", hdr)
    message = str(e.value)
    assert message.startswith(at) and "camera moved" in message, message


@pytest.mark.slow
@pytest.mark.parametrize("at", ["screen/graycode_black", "screen/graycode_21"])
def test_a_bump_where_no_frame_is_compared_is_refused_naming_the_window(
    tmp_path_factory, at: str
) -> None:
    # graycode_black shows no frame; an inverse plane is compared summed with its plane, where a
    # move between the two shows only half: the next comparison refuses, and the message says
    # after which capture the camera was last seen in place
    grabs = _first_grabs("glossy", None, False, tmp_path_factory.mktemp("still"))
    order = list(grabs)
    dev = _device("glossy", None)
    dev.move_camera_during(*grabs[at], _offset(dev.sim.rig, 1.5))
    with pytest.raises(CaptureError) as e:
        _capture(dev, tmp_path_factory.mktemp("bumped") / "c", False)
    message = str(e.value)
    refused = message.split(":")[0].split(" + ")[0]
    found = re.search(r"camera moved \(or was bumped\) after (.+?); fix", message)
    assert found, message
    still = found.group(1)
    assert order.index(still) < order.index(at) <= order.index(refused), message


@pytest.mark.slow
def test_a_jitter_of_a_third_px_is_not_refused(tmp_path: Path) -> None:
    grabs = _first_grabs("glossy", None, False, tmp_path)
    dev = _device("glossy", None)
    dev.move_camera_during(*grabs["screen/ramp"], _offset(dev.sim.rig, 0.3))
    paths = _capture(dev, tmp_path / "c", False)
    assert paths


def test_the_offset_moves_the_frame_by_what_it_says() -> None:
    # the test's own yardstick: 1 mm sideways at 0.5 m with a 30-degree, 180-px-high view
    rig = _rig()
    f = (rig.camera.resolution[1] / 2) / np.tan(np.radians(rig.camera.fov_y) / 2)
    assert _frame_px_per_metre(rig) == pytest.approx(f / 0.5, rel=0.05)


# --- calibrate: a moved capture is refused, naming it ------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["glossy", GLOSSY])
@pytest.mark.parametrize("moved", ["ramp", "graycode_14"])
def test_calibrate_refuses_a_capture_moved_by_one_and_a_half_px(
    materials_dir: Path, kind: str, moved: str
) -> None:
    mats = None if kind == "glossy" else materials_dir
    rig = _rig()
    preset = "default" if kind == "glossy" else "dlp"
    sim = camera_simulator(rig, seed=1, projector=PROJECTOR_PRESETS[preset])
    screen = _screen(kind, mats, sim.shape)
    white = capture_camera_patterns(SimCamera(sim), white_screen(), geometric="chessboard")
    real = capture_camera_patterns(SimCamera(sim), screen)
    dx = _offset(sim.rig, 1.5)[0]
    c = rig.camera
    shifted = replace(
        rig,
        camera=replace(
            c,
            position=(c.position[0] + dx, *c.position[1:]),
            look_at=(c.look_at[0] + dx, *c.look_at[1:]),
        ),
    )
    later = capture_camera_patterns(SimCamera(sim.with_rig(shifted)), screen)
    real[moved] = later[moved]
    if moved.startswith("graycode_"):  # its inverse too: the pair is compared summed
        inverse = f"graycode_{int(moved[9:]) + 1:02d}"
        real[inverse] = later[inverse]
    with pytest.raises(FitError, match=rf"screen/{moved}.*camera moved"):
        calibrate_geometry(capture_set_from_raw(written_rig(rig), white, real))
