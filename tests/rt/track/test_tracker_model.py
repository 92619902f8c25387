"""The shipped face model and the ranging from landmarks: checksum at load, the fallback's
announcement, the interpupillary distance from the command line and rig.toml,
:func:`viewcomp.rt.track.anatomy.head_pose` against exact landmarks (no detector), and the
face height a track learns and ranges a turned face by."""

from __future__ import annotations

import logging
import math
import tomllib
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from viewcomp.calib.world.rig import RigError, rig_from_dict, rig_to_toml
from viewcomp.cli import main
from viewcomp.rt.track.anatomy import (
    FACE_HEIGHT,
    IPD,
    LOOK,
    NOSE_LAG,
    PRIOR_SPREAD,
    face_height,
    head_pose,
    landmarks_of_head,
    nod,
    truncated_mean,
    turn_bounds,
)
from viewcomp.rt.track.faces import DetectorError
from viewcomp.rt.track.run import Pipeline, TrackOptions
from viewcomp.rt.track.simwalk import walk_camera, walk_rig, write_walk
from viewcomp.rt.track.source import ArraySource
from viewcomp.rt.track.tracker import EyeTracker, TrackerConfig
from viewcomp.rt.track.yunet import MODEL_PATH, MODEL_SHA256, YuNetDetector, check_model


def test_the_shipped_model_is_the_one_its_readme_names():
    assert check_model() == MODEL_PATH
    readme = (MODEL_PATH.parent / "README.md").read_text(encoding="utf-8")
    assert MODEL_SHA256 in readme
    assert (MODEL_PATH.parent / "LICENSE-yunet.txt").is_file()


def test_a_damaged_or_missing_model_is_refused_naming_the_file(tmp_path: Path):
    bad = tmp_path / "yunet.onnx"
    bad.write_bytes(MODEL_PATH.read_bytes()[:-10])
    with pytest.raises(DetectorError, match=r"yunet\.onnx is damaged: sha256"):
        YuNetDetector(path=bad)
    with pytest.raises(DetectorError, match=r"nothing\.onnx cannot be read"):
        YuNetDetector(path=tmp_path / "nothing.onnx")


def test_the_cascade_says_it_is_the_fallback(caplog):
    frames = [np.zeros((720, 1280, 3), np.uint8)]
    with caplog.at_level(logging.WARNING, logger="viewcomp"):
        Pipeline(ArraySource(frames), walk_camera(), TrackOptions(detector_kind="cascade"))
    assert "FALLBACK" in caplog.text and "biased" in caplog.text


@pytest.mark.parametrize("yaw_deg", [0.0, 25.0, -45.0])
def test_head_pose_inverts_exact_landmarks(yaw_deg):
    """Exact projections of eyes and nose (the model's geometry) give the eye back within
    1.5 % of its distance at 0.8-3.5 m, 30-150 degrees, frontal or turned 25 degrees; 3 %
    turned 45 (the model treats the head as flat across its line of sight: at 0.8 m the near
    eye is 6 % nearer than the far one, which the separation does not account for)."""
    dev = walk_camera()
    rng = np.random.default_rng(1)
    d = rng.uniform(0.8, 3.5, 40)
    th = np.radians(rng.uniform(50, 130, 40))
    eyes = np.stack([d * np.cos(th), rng.uniform(0.0, 0.3, 40), d * np.sin(th)], axis=-1)
    marks = landmarks_of_head(dev, eyes, math.radians(yaw_deg))
    pose = head_pose(dev, marks)
    true_range = np.linalg.norm(eyes - np.asarray(dev.position), axis=1)
    err = np.linalg.norm(pose.eyes - eyes, axis=1) / true_range
    assert err.max() < (0.03 if abs(yaw_deg) > 30 else 0.015)
    np.testing.assert_allclose(np.degrees(pose.yaw), yaw_deg, atol=2.0)
    # a wider IPD is a proportionally farther viewer
    np.testing.assert_allclose(head_pose(dev, marks, ipd=0.069).range, pose.range * 69 / 63)


def test_ipd_from_rig_and_command_line(tmp_path: Path, capsys):
    """[tracker] ipd round-trips, is validated, and --ipd scales the published distance."""
    rig = replace(walk_rig(), tracker_ipd=0.058)
    again = rig_from_dict(tomllib.loads(rig_to_toml(rig)))
    assert again.tracker_ipd == 0.058
    bad = tomllib.loads(rig_to_toml(rig).replace("ipd = 0.058", "ipd = 63"))
    with pytest.raises(RigError, match="ipd is the viewers' interpupillary distance"):
        rig_from_dict(bad)
    write_walk(tmp_path / "w", seconds=12.0, fps=10.0, frames=3)
    args = ["track", "--camera", str(tmp_path / "w"), "--rig", str(tmp_path / "w" / "rig.toml"),
            "--fps", "10", "--quiet", "--min-cutoff", "1000"]  # fmt: skip
    assert main(args) == 0
    z63 = float(capsys.readouterr().out.splitlines()[-1].split()[3])
    assert main([*args, "--ipd", "0.070"]) == 0
    z70 = float(capsys.readouterr().out.splitlines()[-1].split()[3])
    assert z70 / z63 == pytest.approx(70 / 63, rel=0.02)
    with pytest.raises(SystemExit) as exit_info:
        main([*args, "--ipd", "63"])  # millimetres by mistake
    assert exit_info.value.code == 2 and "metres" in capsys.readouterr().err


def test_nod_is_the_cosine_of_the_cameras_angle_off_the_line_of_sight():
    """A head at 2 m facing the screen's centre, the camera 0.35 m above it: the face's
    eye-to-mouth length is seen shortened by cos(atan(0.35 / 1.98)); facing the camera, not
    at all."""
    dev = walk_camera()
    p = np.asarray(dev.position)
    eye = np.array([[0.0, 0.0, 2.0]])
    assert nod(p, eye, look=tuple(p))[0][0] == pytest.approx(1.0)
    a = math.atan2(p[1], 2.0 - p[2])
    cos_a, sin_a = nod(p, eye)
    assert cos_a[0] == pytest.approx(math.cos(a), rel=1e-9)
    assert sin_a[0] == pytest.approx(-math.sin(a), rel=1e-9)  # the mouth farther than the eyes


def _watching(n: int, seed: int) -> np.ndarray:
    """(n, 3) eye positions, metres: 0.8-3.5 m from the screen's centre at 50-130 degrees,
    0-0.3 m high (where each head faces is the test's)."""
    rng = np.random.default_rng(seed)
    d = rng.uniform(0.8, 3.5, n)
    th = np.radians(rng.uniform(50, 130, n))
    return np.stack([d * np.cos(th), rng.uniform(0.0, 0.3, n), d * np.sin(th)], axis=-1)


def test_face_height_from_exact_landmarks_of_heads_watching_the_screen():
    """Frontal heads facing the screen's centre (nodding against the camera above it by up
    to 25 degrees), mouth 0.07 m below the eyes: the face height comes back within 0.5 %;
    taken as the seen length times the range (no nod, no perspective), up to 10 % short:
    the bias the nod model is about."""
    dev = walk_camera()
    eyes = _watching(40, 3)
    pose = head_pose(dev, landmarks_of_head(dev, eyes, look=LOOK, mouth=0.07))
    np.testing.assert_allclose(face_height(pose), 0.07, rtol=0.005)
    assert np.min(pose.height * pose.range) < 0.07 * 0.92


def _lagging_nose(frontal: np.ndarray, turned: np.ndarray, share: float) -> np.ndarray:
    """``turned`` landmarks with the nose moved only ``share`` as far from its frontal place
    (relative to the eyes' midpoint) as the true nose tip: a detector's nose lagging a turn."""
    out = turned.copy()
    mid_f = frontal[:, :2].mean(axis=1)
    mid_t = turned[:, :2].mean(axis=1)
    lag_from = frontal[:, 2] - mid_f + mid_t  # the frontal nose, carried with the eyes
    out[:, 2] = lag_from + share * (turned[:, 2] - lag_from)
    return out


def test_turn_bounds_and_the_truncated_mean_against_closed_forms():
    """turn_bounds: 1 at no turn; at a read 30 degrees with the nose's offset half the true
    one, tan(true) = 2 tan(30 degrees): cos(true) / cos(30 degrees). truncated_mean against
    scipy's truncated normal, tails included, and the nearer bound where the Gaussian has no
    weight to float precision."""
    from scipy.stats import truncnorm

    lo, hi = turn_bounds(np.array([0.0, math.radians(30.0), -math.radians(30.0)]), 0.5, 1.2)
    assert lo[0] == pytest.approx(1.0) and hi[0] == pytest.approx(1.0)
    t = math.tan(math.radians(30.0))
    want_lo = math.cos(math.atan(2.0 * t)) / math.cos(math.radians(30.0))
    want_hi = math.cos(math.atan(t / 1.2)) / math.cos(math.radians(30.0))
    np.testing.assert_allclose(lo[1:], want_lo, rtol=1e-12)
    np.testing.assert_allclose(hi[1:], want_hi, rtol=1e-12)
    rng = np.random.default_rng(4)
    mean, sd = rng.uniform(0.5, 3.0, 200), rng.uniform(0.01, 0.3, 200)
    a, b = np.sort(rng.uniform(-6.0, 6.0, (2, 200)), axis=0)
    want = truncnorm.mean(a, b, loc=mean, scale=sd)
    got = truncated_mean(mean, sd, mean + a * sd, mean + b * sd)
    np.testing.assert_allclose(got, want, rtol=1e-6)
    far = truncated_mean(np.array([1.0, 1.0]), np.array([0.01, 0.01]),
                         np.array([2.0, 0.1]), np.array([3.0, 0.2]))  # fmt: skip
    np.testing.assert_allclose(far, [2.0, 0.2])


def test_a_viewer_turned_more_than_the_nose_says_is_ranged_by_their_face_height():
    """Four frontal frames teach a track its viewer's face height; the head then turns 45
    degrees with a nose that moves 0.85 as far as it should (a lagging detector: YuNet on
    real photographs, 0.59-1.00 of a hand-marked tip): the IPD's range is 5-7 % long; the
    tracker's lies within what the read turn allows (:func:`turn_bounds`) and within 3 % of
    the truth. With ``face_height`` off, the tracker keeps the IPD's range. A head that
    watches the screen (nodding against the camera) and turns, its nose moving 0.8 as far,
    shows a nose that reads a smaller turn still: the IPD's range 18-31 % long, the range
    allowed narrower, and the tracker's never nearer than the truth nor farther than the
    IPD allows."""
    dev = walk_camera()
    p0 = np.asarray(dev.position)
    for look in (None, LOOK):
        for e in _watching(8, 4):
            truth = np.linalg.norm(e - p0)
            frontal = landmarks_of_head(dev, e[None], 0.0, look=look, mouth=0.07)
            turned = landmarks_of_head(dev, e[None], math.radians(45), look=look, mouth=0.07)
            lagging = head_pose(dev, _lagging_nose(frontal, turned, 0.85 if look is None else 0.8))
            lo, hi = (float(v[0]) * lagging.range[0] for v in turn_bounds(lagging.yaw))
            assert lagging.range[0] > 1.05 * truth
            for on in (True, False):
                tracker = EyeTracker(TrackerConfig(face_height=on))
                for i in range(4):
                    p = head_pose(dev, frontal)
                    tracker.update(p.eyes, np.zeros((1, 4)), i / 10.0, p)
                tracker.update(lagging.eyes, np.zeros((1, 4)), 0.4, lagging)
                # the track that saw the turned face (a face ranged over 0.5 m from where its
                # viewer was is a new track: the gate)
                (tr,) = [t for t in tracker.tracks if t.seen == 0.4]
                got = float(np.linalg.norm(tr.raw - p0))
                if not on:
                    assert got == pytest.approx(lagging.range[0])
                    continue
                assert lo - 1e-9 <= got <= hi + 1e-9, (e, got / truth)
                if look is None:
                    # the height learned as if the head nodded toward the screen (up to 9 %
                    # off near the camera) ranges the head as it was learned: the error cancels
                    assert tr.id == 0 and tr.frontal == 4
                    assert abs(got / truth - 1.0) < 0.03, (e, got / truth)
                else:
                    assert got >= truth, (e, got / truth)


def _first_range(dev, marks: np.ndarray, on: bool = True) -> float:
    """The range (metres from the camera) of the eye a fresh tracker gives a face."""
    p = head_pose(dev, marks)
    (eye,) = EyeTracker(TrackerConfig(face_height=on)).update(p.eyes, np.zeros((1, 4)), 0.0, p)
    return float(np.linalg.norm(eye - np.asarray(dev.position)))


def test_a_viewer_not_yet_measured_is_ranged_by_the_typical_face_height():
    """A face that starts a track (no face height measured), facing the camera, turned 45
    degrees with a nose lagging (0.85 as far as the nose tip): a typical face (FACE_HEIGHT
    IPD) is ranged 5-8 % long by its IPD and within 4 % by a fresh tracker; with the
    nose lagging NOSE_LAG, the most the model allows, within 0.8 PRIOR_SPREAD (the truth at
    the near end of what the turn allows). A face 10 % shorter than typical is never ranged
    nearer than the turn allows, so no nearer than the truth less perspective (the head
    taken as flat: 3-4 %). One 14 % taller (two SD) read with an exact nose: frontal, its
    IPD's range; turned 25-45 degrees ranged by the typical height within the turn's
    interval: up to 4 / 11 % short (at 0.9 m, where the head facing the camera is taken as
    nodding toward the screen's centre). With ``face_height`` off, every face keeps its
    IPD's range."""
    dev = walk_camera()
    p0 = np.asarray(dev.position)
    for e in _watching(12, 5):
        truth = np.linalg.norm(e - p0)

        def marks(turn: float, h: float, share: float, e: np.ndarray = e) -> np.ndarray:
            kw = {"mouth": h * IPD}
            frontal = landmarks_of_head(dev, e[None], 0.0, **kw)
            turned = landmarks_of_head(dev, e[None], math.radians(turn), **kw)
            return _lagging_nose(frontal, turned, share)

        lag = marks(45, FACE_HEIGHT, 0.85)
        ipd_range = head_pose(dev, lag).range[0]
        assert 1.05 * truth < ipd_range < 1.08 * truth
        assert abs(_first_range(dev, lag) / truth - 1.0) < 0.04
        assert _first_range(dev, lag, on=False) == pytest.approx(ipd_range)
        most = marks(45, FACE_HEIGHT, NOSE_LAG)
        assert 0.0 < _first_range(dev, most) / truth - 1.0 < 0.8 * PRIOR_SPREAD
        short = marks(45, 0.9 * FACE_HEIGHT, NOSE_LAG)
        pose = head_pose(dev, short)
        lo, hi = (float(v[0]) * pose.range[0] for v in turn_bounds(pose.yaw))
        assert 0.96 * truth < lo <= _first_range(dev, short) <= hi
        for turn, most_short in ((0, 1e-9), (25, 0.04), (45, 0.11)):
            tall = marks(turn, 1.14 * FACE_HEIGHT, 1.0)
            got = _first_range(dev, tall)
            if turn == 0:
                assert got == pytest.approx(head_pose(dev, tall).range[0])
            assert got / truth > 1.0 - most_short, (turn, e, got / truth)


def test_a_frontal_face_with_its_mouth_misplaced_keeps_the_ipd_range():
    """A viewer known frontal whose mouth landmarks then come 30 % nearer the eyes (a hand
    over the mouth: the detector guesses it): the nose reads no turn, so the IPD's range is
    kept, and the odd height is not taken into the viewer's face height."""
    dev = walk_camera()
    e = np.array([0.4, 0.15, 2.0])
    frontal = landmarks_of_head(dev, e[None], 0.0, look=LOOK, mouth=0.07)
    covered = frontal.copy()
    mid = frontal[:, :2].mean(axis=1)
    covered[:, 3:] = mid[:, None] + 0.7 * (frontal[:, 3:] - mid[:, None])
    tracker = EyeTracker()
    for i in range(4):
        p = head_pose(dev, frontal)
        tracker.update(p.eyes, np.zeros((1, 4)), i / 10.0, p)
    known = tracker.tracks[0].face_height
    p = head_pose(dev, covered)
    tracker.update(p.eyes, np.zeros((1, 4)), 0.4, p)
    (tr,) = tracker.tracks
    np.testing.assert_allclose(tr.raw, p.eyes[0], rtol=1e-5)  # no turn read: the IPD's range
    assert tr.face_height == known


def test_a_pose_of_other_faces_is_refused():
    dev = walk_camera()
    p = head_pose(dev, landmarks_of_head(dev, np.array([[0.0, 0.1, 2.0]]), mouth=0.07))
    with pytest.raises(ValueError, match="pose has 1 faces, eyes 2"):
        EyeTracker().update(np.full((2, 3), 2.0), np.zeros((2, 4)), 0.0, p)


@pytest.mark.parametrize(
    ("flag", "in_track", "in_play"),
    [
        ("--no-face-height", lambda o: o.tracker.face_height,
         lambda p: p.tracker.config.face_height),
        ("--no-mirror", lambda o: o.yunet.mirror,
         lambda p: p.yunet.frame_detector.config.mirror),
    ],
)  # fmt: skip
def test_tracking_switches_reach_track_and_play(tmp_path: Path, flag, in_track, in_play):
    """``--no-face-height`` and ``--no-mirror`` (shared by ``track`` and ``play
    --track-camera``) turn the face height, and YuNet's mirrored second reading of a crop, off
    in the tracker each command builds; both are on by default."""
    from viewcomp.cli import build_parser
    from viewcomp.commands.play import _tracker
    from viewcomp.commands.track import tracker_options

    write_walk(tmp_path / "w", seconds=12.0, fps=10.0, frames=2)
    rig = walk_rig()
    parser = build_parser()
    for extra, on in (([], True), ([flag], False)):
        rig_file = str(tmp_path / "w" / "rig.toml")
        args = parser.parse_args(
            ["track", "--camera", str(tmp_path / "w"), "--rig", rig_file, *extra]
        )
        assert in_track(tracker_options(args, rig)) is on
        args = parser.parse_args(
            ["play", "x.vcb", "clip.mp4", "--track-camera", str(tmp_path / "w"), *extra]
        )
        (thread,) = _tracker(args, rig, False)
        try:
            assert in_play(thread.pipeline) is on  # type: ignore[attr-defined]
        finally:
            thread.pipeline.close()  # type: ignore[attr-defined]


def test_a_coarse_reading_teaches_no_face_height():
    """A newcomer's coarse first reading (frontal) leaves the face height unknown; the first
    refined one teaches it."""
    dev = walk_camera()
    p = head_pose(dev, landmarks_of_head(dev, np.array([[0.2, 0.15, 1.8]]), 0.0, look=LOOK,
                                         mouth=0.07))  # fmt: skip
    tracker = EyeTracker()
    tracker.update(p.eyes, np.zeros((1, 4)), 0.0, p, coarse=np.array([True]))
    (tr,) = tracker.tracks
    assert tr.frontal == 0 and np.isnan(tr.face_height)
    tracker.update(p.eyes, np.zeros((1, 4)), 0.1, p, coarse=np.array([False]))
    assert tr.frontal == 1 and tr.face_height == pytest.approx(0.07, rel=0.005)
