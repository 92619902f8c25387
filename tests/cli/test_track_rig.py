"""The tracking camera on the command line: the `[tracker]` that `simulate` writes, README's
tracking example on a bundle from `simulate`, and `--tracker FILE.toml` (track and play).

The test frames are drawn by the simulated scene (:mod:`viewcomp.rt.track.simscene`: a real
photograph placed by its hand-located eyes at a 63 mm IPD) for a camera the test chooses;
the tracker is only told the camera through the rig or ``--tracker``.
"""

from __future__ import annotations

import os
import shutil
import subprocess
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest

from viewcomp.calib.fit.calibrate import Calibration
from viewcomp.calib.world.eye import eye_from_angle
from viewcomp.calib.world.rig import Device, load_rig
from viewcomp.calib.world.tracker import default_tracker, load_tracker_file, picture_top
from viewcomp.cli import main
from viewcomp.rt.play.live import SetEye, parse_line
from viewcomp.rt.track.simwalk import render_walk

ROOT = Path(__file__).resolve().parents[2]
VIEWCOMP = str(ROOT / ".venv" / "bin" / "viewcomp")

# Eyes to draw: 1.2-2.4 m from the screen, 70-110 degrees, about the viewer's height.
TRUTH = np.array([eye_from_angle(a, d, 0.05) for a, d in ((90, 1.2), (75, 1.8), (105, 2.4))])


@pytest.fixture(scope="module")
def bundle(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A bundle calibrated from `viewcomp simulate` (a small grid), as README's session."""
    d = tmp_path_factory.mktemp("sim")
    assert main(["simulate", str(d / "caps"), "--size", "64x32"]) == 0
    assert main(["calibrate", str(d / "caps"), "-o", str(d / "screen.vcb")]) == 0
    return d / "screen.vcb"


def _frames(folder: Path, device: Device, eyes: np.ndarray = TRUTH, repeat: int = 1) -> Path:
    """Each eye seen by ``device`` in a folder of its own (``folder/0``, ...), ``repeat``
    PNG frames each."""
    for k, eye in enumerate(eyes):
        (folder / str(k)).mkdir(parents=True)
        for i, frame in enumerate(render_walk(device, np.repeat(eye[None], repeat, 0), seed=k)):
            assert cv2.imwrite(str(folder / str(k) / f"f_{i:03d}.png"), frame)
    return folder


def _published(out: str) -> np.ndarray:
    """The eyes of `eye X Y Z` lines, (n, 3)."""
    cmds = [parse_line(line) for line in out.splitlines()]
    assert cmds and all(isinstance(c, SetEye) for c in cmds), out[:400]
    return np.array([c.eye for c in cmds])  # type: ignore[union-attr]


def _eye_per_pose(argv: list[str], frames: Path, capsys: pytest.CaptureFixture[str]) -> np.ndarray:
    """`viewcomp track --camera frames/k ARGV...` for each pose k: the eye it published on
    the pose's one frame (the first estimate, unfiltered), (k, 3)."""
    eyes = []
    for k in range(len(TRUTH)):
        code = main(["track", "--camera", str(frames / str(k)), *argv, "--quiet"])
        out, err = capsys.readouterr()
        assert code == 0, err
        eyes.append(_published(out)[-1])
    return np.array(eyes)


def _close(got: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """Per row: within 10 cm in x and y and 10 % in distance from the screen centre."""
    dist = np.linalg.norm(got, axis=1) / np.linalg.norm(truth, axis=1)
    return np.all(np.abs(got[:, :2] - truth[:, :2]) < 0.1, axis=1) & (np.abs(dist - 1) < 0.1)


# ----------------------------------------------------------------------- simulate's [tracker]
def test_simulate_writes_a_tracker_above_the_picture_facing_the_audience(bundle: Path):
    rig = load_rig(bundle.parent / "caps" / "rig.toml")
    t = rig.tracker
    assert t is not None and rig == Calibration.load(bundle).rig
    x, top = picture_top(rig.projector)
    # the picture's top edge: the projector at (0, -0.03, 0.5) aims at the origin (tilted up
    # by atan(0.03 / 0.5)) and its top row is 8 degrees (half of fov_y 16) above its axis
    tilt = np.degrees(np.arctan2(0.03, 0.5))
    assert top == pytest.approx(-0.03 + 0.5 * np.tan(np.radians(tilt + 8.0)), abs=1e-3)
    assert t.position[1] > top and 0 < t.position[2] <= 0.05 and abs(t.position[0] - x) < 1e-3
    rot, _ = t.pose()
    assert rot[2, 2] > 0.9  # looks toward +z, the audience
    assert t.resolution == (1280, 720) and 40 < t.fov_y < 70  # a 720p webcam


def test_readme_tracking_example_on_a_simulate_bundle(bundle: Path, tmp_path: Path, capsys):
    """`viewcomp track --camera SRC --rig screen.vcb` (README, Track.) on frames of the
    bundle's own tracking camera: runs, and the eyes are where the faces were drawn."""
    device = Calibration.load(bundle).rig.tracker
    assert device is not None
    frames = _frames(tmp_path / "frames", device)
    got = _eye_per_pose(["--rig", str(bundle)], frames, capsys)
    assert np.all(_close(got, TRUTH)), np.round(got - TRUTH, 3)


# ----------------------------------------------------------------------- --tracker FILE.toml
def _moved() -> Device:
    """A webcam 0.4 m to the right of the picture, 0.2 m higher, turned toward the middle."""
    return Device(resolution=(1280, 720), position=(0.4, 0.3, 0.03),
                  look_at=(0.0, 0.05, 1.8), up=(0.0, 1.0, 0.0), fov_y=45.0)  # fmt: skip


def test_track_tracker_file_replaces_the_bundles_camera(bundle: Path, tmp_path: Path, capsys):
    frames = _frames(tmp_path / "frames", _moved())
    toml = tmp_path / "webcam.toml"
    toml.write_text(
        "# the kiosk's webcam, measured\n[tracker]\nresolution = [1280, 720]\n"
        "position = [0.4, 0.3, 0.03]\nlook_at = [0.0, 0.05, 1.8]\nup = [0.0, 1.0, 0.0]\n"
        "fov_y = 45.0\nipd = 0.063\n"
    )
    assert load_tracker_file(toml) == (_moved(), 0.063)
    moved = _eye_per_pose(["--rig", str(bundle), "--tracker", str(toml)], frames, capsys)
    assert np.all(_close(moved, TRUTH)), np.round(moved - TRUTH, 3)
    # the bundle's own camera (another pose and field of view) puts the same faces elsewhere
    wrong = _eye_per_pose(["--rig", str(bundle)], frames, capsys)
    assert not np.any(_close(wrong, TRUTH)), np.round(wrong - TRUTH, 3)


def test_a_whole_rig_toml_works_as_tracker_file(bundle: Path, tmp_path: Path):
    rig = Calibration.load(bundle).rig
    from viewcomp.calib.world.rig import rig_to_toml

    path = tmp_path / "rig.toml"
    path.write_text(rig_to_toml(replace(rig, tracker=_moved(), tracker_ipd=None)))
    assert load_tracker_file(path) == (_moved(), None)


_KEYS = "[tracker]\nresolution = [1280, 720]\nposition = [0, 0.3, 0.02]\nup = [0, 1, 0]\n"
BAD_FILES = [
    (None, "no such file; --tracker takes a TOML file with a [tracker] table"),
    ("[trackr]\nfov_y = 40\n", "no [tracker] table (found [trackr]); write the tracking"),
    ("[tracker]\nresolution = [1280, 720\n", "invalid TOML"),
    (_KEYS + "look_at = [0, 0, 2]\nfov = 40\n", '[tracker] unknown key "fov" (did you mean'),
    (_KEYS + "look_at = [0, 0.3, 0.02]\nfov_y = 40\n", "look_at must differ from position"),
    (_KEYS + "look_at = [0, 0, -2]\nfov_y = 40\n", "looks toward the screen"),
    (_KEYS + "look_at = [0, 0, 2]\nfov_y = 40\nipd = 63\n", "ipd is the viewers' interpupillary"),
]


@pytest.mark.parametrize(("text", "says"), BAD_FILES)
@pytest.mark.parametrize("command", ["track", "play"])
def test_a_bad_tracker_file_is_exit_2_naming_it(
    bundle: Path, tmp_path: Path, capsys, text: str | None, says: str, command: str
):
    path = tmp_path / "webcam.toml"
    if text is not None:
        path.write_text(text)
    frames = tmp_path / "frames"
    frames.mkdir()
    if command == "track":
        argv = ["track", "--camera", str(frames), "--rig", str(bundle)]
    else:
        argv = ["play", str(bundle), str(tmp_path / "clip.mp4"), "--track-camera", str(frames)]
    assert main([*argv, "--tracker", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"viewcomp {command}: error: ") and str(path) in err and says in err


def test_play_tracker_without_track_camera_is_a_usage_error(bundle: Path, tmp_path: Path, capsys):
    with pytest.raises(SystemExit) as e:  # a usage error exits as argparse's do
        main(["play", str(bundle), "clip.mp4", "--tracker", str(tmp_path / "w.toml")])
    assert e.value.code == 2
    assert "give --track-camera SRC too" in capsys.readouterr().err


def test_play_ipd_is_checked_as_for_track(bundle: Path, tmp_path: Path, capsys):
    (tmp_path / "frames").mkdir()
    argv = ["play", str(bundle), "clip.mp4", "--track-camera", str(tmp_path / "frames")]
    with pytest.raises(SystemExit) as e:
        main([*argv, "--ipd", "63"])
    assert e.value.code == 2
    assert "--ipd 63: the interpupillary distance is in metres" in capsys.readouterr().err


def test_default_tracker_follows_the_rigs_geometry():
    """Another projector (farther, higher) and viewer: the webcam moves with the picture."""
    from viewcomp.calib.sim.simulator import simulation_rig

    rig = simulation_rig()
    proj = replace(rig.projector, position=(0.2, 0.5, 2.0), look_at=(0.2, 0.5, 0.0))
    viewer = replace(rig.viewer, distance=3.0, height=1.6)
    t = default_tracker(replace(rig, projector=proj, viewer=viewer, tracker=None))
    half = 2.0 * np.tan(np.radians(rig.projector.fov_y / 2))
    assert t.position == pytest.approx((0.2, 0.5 + half + 0.03, 0.02), abs=1e-3)
    assert t.look_at == pytest.approx((0.0, 1.6, 3.0))


# ----------------------------------------------------------------------- README, as written
@pytest.mark.gl
@pytest.mark.slow
def test_readme_track_pipe_into_play_runs(bundle: Path, tmp_path: Path):
    """README's `viewcomp track --camera 0 --rig screen.vcb | viewcomp play screen.vcb
    clip.mp4`, camera 0 replaced by frames of the bundle's webcam (paced as a camera), the
    player windowed for 10 s under Xvfb (the tracker's side ends sooner): both ends exit 0,
    and the player's status (stdin `status`, after the tracker's lines) has the tracked eye."""
    from tests.support.synthetic import make_test_video
    from viewcomp.rt.play.xvfb import Xvfb, xvfb_available

    if not xvfb_available() or shutil.which("bash") is None:
        pytest.skip("Xvfb is not installed (Debian package xvfb)")
    device = Calibration.load(bundle).rig.tracker
    assert device is not None
    _frames(tmp_path / "frames", device, TRUTH[:1], repeat=10)  # frames/0
    make_test_video(str(tmp_path / "clip.mp4"), 128, 64, seconds=6.0, rate=30, audio=False)
    pipe = (
        f"set -o pipefail; ({VIEWCOMP} track --camera frames/0 --rig screen.vcb --realtime "
        f"--fps 10; sleep 0.5; echo status) | {VIEWCOMP} play screen.vcb clip.mp4 "
        "--windowed --no-audio --seconds 10 --loop --eye-smooth 0"
    )
    shutil.copy(bundle, tmp_path / "screen.vcb")
    with Xvfb((640, 360)):
        r = subprocess.run(["bash", "-c", pipe], cwd=tmp_path, capture_output=True,
                           text=True, timeout=120, env=dict(os.environ))  # fmt: skip
    assert r.returncode == 0, r.stderr[-2000:]
    status = [ln for ln in r.stdout.splitlines() if ln.startswith("status ")]
    assert status, r.stdout[-1000:] + r.stderr[-1000:]
    eye = np.array([float(v) for v in status[-1].split(" eye=")[1].split()[0].split(",")])
    assert _close(eye[None], TRUTH[:1])[0], (status[-1], TRUTH[0])


@pytest.mark.gl
@pytest.mark.slow
def test_play_track_camera_with_a_tracker_file(bundle: Path, tmp_path: Path):
    """`viewcomp play screen.vcb clip.mp4 --track-camera SRC --tracker webcam.toml --ipd M`:
    frames of a webcam moved away from the bundle's, given by the file alone; the player's
    last status (stdin `status` every second for 8 s) has the eye where the face was drawn."""
    from tests.support.synthetic import make_test_video
    from viewcomp.rt.play.xvfb import Xvfb, xvfb_available

    if not xvfb_available():
        pytest.skip("Xvfb is not installed (Debian package xvfb)")
    _frames(tmp_path / "frames", _moved(), TRUTH[1:2], repeat=5)  # frames/0
    (tmp_path / "webcam.toml").write_text(
        "[tracker]\nresolution = [1280, 720]\nposition = [0.4, 0.3, 0.03]\n"
        "look_at = [0.0, 0.05, 1.8]\nup = [0.0, 1.0, 0.0]\nfov_y = 45.0\n"
    )
    make_test_video(str(tmp_path / "clip.mp4"), 128, 64, seconds=6.0, rate=30, audio=False)
    shutil.copy(bundle, tmp_path / "screen.vcb")
    cmd = (
        "(for i in 1 2 3 4 5 6 7 8; do sleep 1; echo status; done) | "
        f"{VIEWCOMP} play screen.vcb clip.mp4 --track-camera frames/0 --tracker webcam.toml "
        "--ipd 0.063 --windowed --no-audio --loop --seconds 10 --eye-smooth 0"
    )
    with Xvfb((640, 360)):
        r = subprocess.run(["bash", "-c", cmd], cwd=tmp_path, capture_output=True, text=True,
                           timeout=120, env=dict(os.environ))  # fmt: skip
    assert r.returncode == 0, r.stderr[-2000:]
    status = [ln for ln in r.stdout.splitlines() if ln.startswith("status ")]
    assert status, r.stdout[-1000:] + r.stderr[-1000:]
    eye = np.array([float(v) for v in status[-1].split(" eye=")[1].split()[0].split(",")])
    assert _close(eye[None], TRUTH[1:2])[0], (status[-1], TRUTH[1])
