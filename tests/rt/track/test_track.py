"""viewcomp track: the One-Euro filter, face box <-> eye, the simulated walk, losing a face,
several faces, the command line and its errors, the [tracker] section of rig.toml (no GL)."""

from __future__ import annotations

import math
import socket
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from viewcomp.calib.world.rig import (
    RigError,
    default_rig,
    load_rig,
    rig_from_dict,
    rig_to_toml,
    tracking_camera,
)
from viewcomp.cli import main
from viewcomp.rt.play.live import InputHub, OscListener, SetEye, parse_line
from viewcomp.rt.track.filter import OneEuroFilter
from viewcomp.rt.track.pose import (
    boxes_from_eyes,
    camera_for_frames,
    distance_from,
    eyes_from_boxes,
)
from viewcomp.rt.track.publish import HubPublisher, LinePublisher, OscPublisher, format_eyes
from viewcomp.rt.track.run import Pipeline, TrackOptions
from viewcomp.rt.track.simwalk import (
    background,
    render_frame,
    render_walk,
    walk,
    walk_camera,
    write_walk,
)
from viewcomp.rt.track.source import ArraySource
from viewcomp.rt.track.tracker import EyeTracker, TrackerConfig


# ----------------------------------------------------------------------- One-Euro filter
def test_one_euro_returns_a_constant_unchanged():
    f = OneEuroFilter(min_cutoff=1.0, beta=2.0)
    x = np.array([0.3, -0.2, 1.7])
    for i in range(50):
        assert np.array_equal(f(x, i / 30), x)


def test_one_euro_step_converges_at_least_as_fast_as_at_rest():
    """After a step the cutoff is >= min_cutoff, so the error shrinks at least by
    (1 - alpha(min_cutoff)) per sample, and the output never overshoots."""
    te, mc = 1 / 30, 1.0
    f = OneEuroFilter(min_cutoff=mc, beta=0.5)
    f(np.zeros(1), 0.0)
    a_min = float(OneEuroFilter.alpha(mc, te))
    prev = 0.0
    for n in range(1, 200):
        y = float(f(np.ones(1), n * te)[0])
        assert prev <= y <= 1.0
        assert 1.0 - y <= (1.0 - a_min) ** n + 1e-12
        prev = y
    assert 1.0 - prev < 1e-6


@pytest.mark.parametrize("beta", [0.0, 0.7, 3.0])
def test_one_euro_ramp_lag_is_the_closed_form(beta):
    """Settled on a ramp of slope v, the speed estimate is v and the output lags by exactly
    v / (2 pi (min_cutoff + beta |v|))."""
    te, mc, v = 1 / 60, 1.5, 0.8
    f = OneEuroFilter(min_cutoff=mc, beta=beta, d_cutoff=1.0)
    for n in range(3000):
        y = float(f(np.array([v * n * te]), n * te)[0])
    lag = v * (3000 - 1) * te - y
    assert lag == pytest.approx(v / (2 * math.pi * (mc + beta * abs(v))), rel=1e-9)


def test_one_euro_rejects_bad_parameters():
    with pytest.raises(ValueError, match="min_cutoff"):
        OneEuroFilter(min_cutoff=0.0)


# ----------------------------------------------------------------------- pose
def _eyes_in_view(n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    d = rng.uniform(0.8, 3.5, n)
    th = np.radians(rng.uniform(50, 130, n))
    return np.stack([d * np.cos(th), rng.uniform(-0.1, 0.4, n), d * np.sin(th)], axis=-1)


def test_pose_round_trip():
    dev = walk_camera()
    eyes = _eyes_in_view(200)
    boxes = boxes_from_eyes(dev, eyes)
    assert np.all(boxes[:, 2] > 0) and np.all(np.isfinite(boxes))
    np.testing.assert_allclose(eyes_from_boxes(dev, boxes), eyes, atol=1e-9)
    # a face at depth Z is f W / Z wide: 0.15 m at 2 m on the camera's axis
    rot, _ = dev.pose()
    on_axis = np.asarray(dev.position) + 2.0 * rot[2]
    assert boxes_from_eyes(dev, on_axis[None])[0, 2] == pytest.approx(dev.focal() * 0.15 / 2)


def test_pose_round_trip_with_a_lens_and_another_frame_size():
    dev = replace(walk_camera(), distortion=(-0.1, 0.02, 0.0, 0.0, 0.0))
    eyes = _eyes_in_view(50, seed=1)
    np.testing.assert_allclose(eyes_from_boxes(dev, boxes_from_eyes(dev, eyes)), eyes, atol=1e-6)
    half = camera_for_frames(dev, (640, 360))
    boxes = boxes_from_eyes(half, eyes)
    np.testing.assert_allclose(boxes[:, 2], boxes_from_eyes(dev, eyes)[:, 2] / 2, rtol=1e-9)
    np.testing.assert_allclose(eyes_from_boxes(half, boxes), eyes, atol=1e-6)
    with pytest.raises(ValueError, match="640x480"):
        camera_for_frames(dev, (640, 480))


# ----------------------------------------------------------------------- the walk
def _errors(dev, est: np.ndarray, truth: np.ndarray) -> dict[str, np.ndarray]:
    """Per frame: world x and y errors (m), the error across the camera's line of sight to
    the true eye (m) and the range error along it (relative)."""
    err = est - truth
    ray = truth - np.asarray(dev.position)
    rng = np.linalg.norm(ray, axis=1)
    u = ray / rng[:, None]
    along = np.sum(err * u, axis=1)
    return {
        "x": np.abs(err[:, 0]),
        "y": np.abs(err[:, 1]),
        "across": np.linalg.norm(err - along[:, None] * u, axis=1),
        "range": np.abs(distance_from(dev, est) / rng - 1.0),
    }


@pytest.mark.slow
def test_walk_is_tracked_within_the_tolerances():
    """The issue's criterion on a simulated walk (1..3 m, 90 +- 40 degrees, 12 s at 30 fps):
    the eye within 10 cm in world x and y and within 20 % in distance in 95 % of frames.

    Also within 10 cm across the camera's line of sight. The astronaut is placed by her
    hand-located eyes at a 63 mm IPD (it was placed by the cascade's box, which hid that
    convention's bias) and ranged by YuNet's landmarks: 95.0 % of frames (p95: range 6.6 %,
    x 9.9 cm, across 1.9 cm; with the render noise of seeds 0 and 1, 97.8 % and 98.9 %). Each
    small face's crop read mirrored too ranges her 4 % short (median) where a single reading
    ranged her 2 % short: 100 %, 4.8 %, 7.1 cm, 2.1 cm read once (``YuNetConfig.mirror``
    off); 98.9 %, 5.6 %, 7.9 cm, 2.3 cm before her head's relief was corrected, 2026-11-29;
    x 7.3 cm before the nose model from anatomy.
    """
    dev = walk_camera()
    _, truth = walk(12.0, 30.0)
    frames = render_walk(dev, truth, seed=3)
    pipeline = Pipeline(ArraySource(frames, 30.0), dev, TrackOptions())
    est = np.array([pipeline.step(f).eyes[0] for f in pipeline.source])
    e = _errors(dev, est, truth)
    share = {
        "across<=10cm": float(np.mean(e["across"] <= 0.10)),
        "range<=20%": float(np.mean(e["range"] <= 0.20)),
        "y<=10cm": float(np.mean(e["y"] <= 0.10)),
        "x<=10cm": float(np.mean(e["x"] <= 0.10)),
        "x, y and range": float(np.mean((e["x"] <= 0.1) & (e["y"] <= 0.1) & (e["range"] <= 0.2))),
    }
    print("\nwalk:", {k: f"{v:.1%}" for k, v in share.items()},
          f"p95 across {np.percentile(e['across'], 95):.3f} m, range "
          f"{np.percentile(e['range'], 95):.1%}, x {np.percentile(e['x'], 95):.3f} m")  # fmt: skip
    assert pipeline.stats.with_face == len(frames)
    assert share["x, y and range"] >= 0.95
    assert share["across<=10cm"] >= 0.95


def test_templates_size_a_face_finer_than_the_cascade():
    """A face first seen near, then at 2.6 m and 40 degrees aside: its template gives the
    width within 3 % of the truth; it finds nothing where the face is not."""
    import cv2

    from viewcomp.rt.track.faces import FaceDetector
    from viewcomp.rt.track.scale import FaceTemplate, ScaleConfig

    dev = walk_camera()
    near = np.array([[0.2, 0.15, 1.1]])
    th = math.radians(130)
    far = np.array([[2.6 * math.cos(th), 0.15, 2.6 * math.sin(th)]])
    # the cascade's box convention is what this test is about: flat faces placed by it
    frames = [cv2.cvtColor(f, cv2.COLOR_BGR2GRAY)
              for f in render_walk(dev, np.stack([near, far]), by_box=True)]  # fmt: skip
    det = FaceDetector()
    box_near = det.detect(frames[0])[0]
    template = FaceTemplate(frames[0], box_near)
    truth = boxes_from_eyes(dev, far)[0]
    box_far = det.detect(frames[1])[0]
    found = template.measure(frames[1], box_far, ScaleConfig())
    assert found is not None
    ratio_near = box_near[2] / boxes_from_eyes(dev, near)[0, 2]
    assert found[0][2] / truth[2] == pytest.approx(ratio_near, rel=0.03)
    assert template.measure(frames[1], box_far - np.array([300.0, 0, 0, 0]), ScaleConfig()) is None


def test_faces_are_found_near_and_far():
    """One frame at 1 m in front and one at 3 m, 40 degrees aside: found, within tolerance."""
    dev = walk_camera()
    truth = np.array([[0.0, 0.15, 1.0], [3 * math.cos(math.radians(130)), 0.15,
                                         3 * math.sin(math.radians(130))]])  # fmt: skip
    frames = render_walk(dev, truth, seed=1)
    pipeline = Pipeline(ArraySource(frames), dev, TrackOptions())
    for frame, eye in zip(pipeline.source, truth, strict=True):
        pipeline.tracker = EyeTracker(pipeline.options.tracker)  # each frame on its own
        raw = pipeline.step(frame).raw
        assert len(raw) == 1
        e = _errors(dev, raw, eye[None])
        assert e["across"][0] <= 0.1 and e["range"][0] <= 0.2


# ----------------------------------------------------------------------- losing a face
def test_a_lost_face_is_held_then_eases_to_the_default():
    default = (0.0, 0.1, 2.0)
    cfg = TrackerConfig(default_eye=default, hold=1.0, ease=2.0)
    tr = EyeTracker(cfg)
    none3, none4 = np.zeros((0, 3)), np.zeros((0, 4))
    np.testing.assert_array_equal(tr.update(none3, none4, 0.0)[0], default)  # nobody yet
    seen = np.array([[0.5, 0.2, 1.5]])
    box = np.array([[600.0, 300.0, 60.0, 60.0]])
    for i in range(10):  # standing still: the filter returns the constant
        out = tr.update(seen, box, 0.1 * i)
    np.testing.assert_array_equal(out[0], seen[0])
    last = 0.9
    np.testing.assert_array_equal(tr.update(none3, none4, last + 0.5)[0], seen[0])
    np.testing.assert_array_equal(tr.update(none3, none4, last + 1.0)[0], seen[0])
    mid = tr.update(none3, none4, last + 1.0 + 1.0)[0]  # half way through the ease
    np.testing.assert_allclose(mid, (seen[0] + np.array(default)) / 2, atol=1e-12)
    np.testing.assert_array_equal(tr.update(none3, none4, last + 3.0)[0], default)
    assert tr.tracks == []
    # back somewhere else: no smoothing from where the face was lost
    back = np.array([[-0.4, 0.2, 1.2]])
    np.testing.assert_array_equal(tr.update(back, box, 10.0)[0], back[0])


def test_losing_the_face_in_frames():
    """Frames: the face for 1 s, then an empty room: the eye is held, then the default."""
    dev = walk_camera()
    fps = 10.0
    eye = np.array([0.3, 0.15, 1.5])
    back = background(dev.resolution, 2)
    rng = np.random.default_rng(0)
    frames = [render_frame(dev, eye[None], back, rng) for _ in range(10)]
    frames += [render_frame(dev, np.zeros((0, 3)), back, rng) for _ in range(20)]
    default = (0.0, 0.1, 2.0)
    opts = TrackOptions(tracker=TrackerConfig(default_eye=default, hold=0.5, ease=0.5))
    pipeline = Pipeline(ArraySource(frames, fps), dev, opts)
    out = np.array([pipeline.step(f).eyes[0] for f in pipeline.source])
    held = out[9]
    # the face's eye, within the tracker's tolerances (10 cm in x and y, 10 % in distance)
    p = np.asarray(dev.position)
    assert np.all(np.abs(held - eye)[:2] < 0.1), held
    assert abs(np.linalg.norm(held - p) / np.linalg.norm(eye - p) - 1.0) < 0.1, held
    np.testing.assert_array_equal(out[10:15], np.repeat(held[None], 5, axis=0))  # <= 0.5 s
    assert 0 < np.linalg.norm(out[16] - held) < np.linalg.norm(np.array(default) - held)
    np.testing.assert_array_equal(out[-1], default)


# ----------------------------------------------------------------------- several faces
def test_several_faces_nearest_and_all(tmp_path: Path):
    dev = walk_camera()
    eyes = np.array([[-0.6, 0.15, 2.2], [0.5, 0.12, 1.3]])
    frames = render_walk(dev, np.repeat(eyes[None], 3, axis=0), seed=2)
    results = {}
    for faces in ("nearest", "all"):
        opts = TrackOptions(tracker=TrackerConfig(faces=faces))
        pipeline = Pipeline(ArraySource(frames), dev, opts)
        results[faces] = [pipeline.step(f).eyes for f in pipeline.source][-1]
    assert results["nearest"].shape == (1, 3)
    assert np.linalg.norm(results["nearest"][0] - eyes[1]) < 0.15  # the nearer viewer
    got = results["all"]
    assert got.shape == (2, 3)
    for g, want in zip(got, eyes[::-1], strict=True):  # nearest first
        assert np.linalg.norm(g - want) < 0.25
    line = format_eyes(got, all_faces=True)
    assert line.startswith("eyes ") and len(line.split()) == 7
    # OSC /viewcomp/eyes with 3k floats, received on 127.0.0.1
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", 0))
    rx.settimeout(5.0)
    pub = OscPublisher("127.0.0.1", rx.getsockname()[1], all_faces=True)
    try:
        assert pub.publish(got)
        data, _ = rx.recvfrom(65536)
    finally:
        pub.close()
        rx.close()
    from pythonosc.osc_message import OscMessage

    msg = OscMessage(data)
    assert msg.address == "/viewcomp/eyes"
    np.testing.assert_allclose(msg.params, np.round(got.ravel(), 4), atol=1e-6)


# ----------------------------------------------------------------------- publishing
def test_lines_and_osc_are_what_the_player_reads():
    import io

    eye = np.array([[0.12345, -0.05, 1.5]])
    stream = io.StringIO()
    pub = LinePublisher(stream)
    assert pub.publish(eye) and not pub.publish(eye)  # unchanged: not sent again
    assert stream.getvalue() == "eye 0.1235 -0.0500 1.5000\n"
    assert parse_line(stream.getvalue()) == SetEye((0.1235, -0.05, 1.5))

    hub = InputHub()
    with OscListener(hub, "127.0.0.1", 0) as listener:
        osc = OscPublisher(*listener.address)
        try:
            assert osc.publish(eye)
            for _ in range(100):
                got = hub.drain()
                if got:
                    break
                import time

                time.sleep(0.02)
        finally:
            osc.close()
    assert len(got) == 1 and isinstance(got[0].command, SetEye)
    np.testing.assert_allclose(got[0].command.eye, (0.1235, -0.05, 1.5), atol=1e-6)  # float32

    hub2 = InputHub()
    assert HubPublisher(hub2).publish(eye)
    item = hub2.drain()[0]
    assert (item.source, item.command) == ("track", SetEye((0.1235, -0.05, 1.5)))


# ----------------------------------------------------------------------- command line
def test_cli_on_an_image_sequence_writes_eye_lines(tmp_path: Path, capsys):
    _, truth = write_walk(tmp_path / "walk", seconds=12.0, fps=10.0, frames=20)
    code = main(["track", "--camera", str(tmp_path / "walk"), "--rig",
                 str(tmp_path / "walk" / "rig.toml"), "--fps", "10"])  # fmt: skip
    out, err = capsys.readouterr()
    assert code == 0, err
    lines = out.splitlines()
    assert len(lines) >= 10 and "20 frames" in err
    commands = [parse_line(line) for line in lines]
    assert all(isinstance(c, SetEye) for c in commands)
    last = np.array(commands[-1].eye)  # type: ignore[union-attr]
    assert np.linalg.norm(last - truth[-1]) < 0.3


def test_cli_glob_and_osc(tmp_path: Path, capsys):
    write_walk(tmp_path / "w", fps=10.0, frames=5)
    hub = InputHub()
    with OscListener(hub, "127.0.0.1", 0) as listener:
        code = main(["track", "--camera", str(tmp_path / "w" / "frame_*.png"), "--rig",
                     str(tmp_path / "w"), "--osc", f"127.0.0.1:{listener.address[1]}",
                     "--no-stdout", "--faces", "nearest", "--quiet"])  # fmt: skip
        import time

        time.sleep(0.3)
    out, err = capsys.readouterr()
    assert code == 0, err
    assert out == "" and err == ""
    assert hub.snapshot()["osc"].received >= 1


@pytest.mark.parametrize(
    ("src", "says"),
    [
        ("missing/folder", "no such camera, file or folder"),
        ("empty", "a folder without images"),
        ("nothing_*.png", "no files match"),
        ("not-a-video.mp4", "not a video"),
        ("97", "no camera with this index"),
    ],
)
def test_cli_bad_source_is_exit_2_with_a_clear_message(tmp_path: Path, capsys, src, says):
    (tmp_path / "empty").mkdir()
    (tmp_path / "not-a-video.mp4").write_bytes(b"junk" * 10)
    rig = tmp_path / "rig.toml"
    rig.write_text(rig_to_toml(replace(default_rig(), tracker=walk_camera())))
    arg = src if src.isdigit() else str(tmp_path / src)
    assert main(["track", "--camera", arg, "--rig", str(rig)]) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert err.startswith("viewcomp track: error: --camera ") and says in err
    assert "give a camera index" in err


def test_cli_rig_without_a_camera_facing_the_audience(tmp_path: Path, capsys):
    rig = tmp_path / "rig.toml"
    rig.write_text(rig_to_toml(default_rig()))  # [camera] looks at the screen, no [tracker]
    assert main(["track", "--camera", "0", "--rig", str(rig)]) == 2
    assert "add a [tracker] section" in capsys.readouterr().err


# ----------------------------------------------------------------------- rig.toml
def test_tracker_section_round_trip_and_fallback(tmp_path: Path):
    rig = replace(default_rig(), tracker=walk_camera())
    path = tmp_path / "rig.toml"
    path.write_text(rig_to_toml(rig))
    back = load_rig(path)
    assert back == rig
    assert tracking_camera(back) == rig.tracker
    facing = replace(default_rig().camera, look_at=(0.0, 0.0, 2.0))
    plain = replace(default_rig(), camera=facing)
    assert plain.tracker is None and tracking_camera(plain) == facing
    with pytest.raises(RigError, match="add a \\[tracker\\] section"):
        tracking_camera(default_rig())


def test_tracker_section_is_validated():
    import tomllib

    d = tomllib.loads(rig_to_toml(replace(default_rig(), tracker=walk_camera())))
    d["tracker"]["fov"] = 50
    with pytest.raises(RigError, match=r'\[tracker\] unknown key "fov" \(did you mean "fov_y"'):
        rig_from_dict(d)
    del d["tracker"]["fov"]
    d["tracker"]["resolution"] = [1280]
    with pytest.raises(RigError, match=r"\[tracker\] resolution must be"):
        rig_from_dict(d)


# ----------------------------------------------------------------------- the player
@pytest.mark.gl
@pytest.mark.slow
@pytest.mark.usefixtures("session_gl_current")
def test_player_follows_the_tracker(tmp_path: Path):
    """play --track-camera: the tracker's thread feeds the player's input queue; the eye the
    player draws with is the one the tracker published last."""
    from tests.support.calibrations import small_calibration
    from tests.support.synthetic import make_test_video
    from viewcomp.rt.play.player import Player, PlayerOptions
    from viewcomp.rt.play.xvfb import Xvfb, xvfb_available
    from viewcomp.rt.track.run import TrackerThread
    from viewcomp.rt.track.source import FrameSource

    if not xvfb_available():
        pytest.skip("Xvfb is not installed (Debian package xvfb)")
    write_walk(tmp_path / "walk", fps=10.0, frames=15)
    clip = tmp_path / "clip.mp4"
    make_test_video(str(clip), 128, 64, seconds=4.0, rate=30, audio=False)
    cal = small_calibration(64, 32, screen="magenta")
    source = FrameSource(str(tmp_path / "walk"), fps=10.0, realtime=True)
    tracker = TrackerThread(Pipeline(source, walk_camera(), TrackOptions()))
    published = LinePublisher(__import__("io").StringIO())
    tracker.pipeline.publishers.append(published)
    drawn: list[tuple[float, ...]] = []

    def on_frame(player, f) -> None:
        drawn.append(tuple(f.record.eye))
        counts = player.hub.snapshot().get("track")
        settled = counts is not None and counts.applied == published.sent
        # the sequence has ended and its last eye was applied before this frame was drawn
        if not tracker._thread.is_alive() and len(drawn) > 5 and settled:
            player.stop()

    opts = PlayerOptions(windowed=True, audio=False, stdin_fd=None, max_seconds=20.0,
                         eye_tau=0.0, loop=True, inputs=(tracker,))  # fmt: skip
    with Xvfb((640, 360)):
        stats = Player(cal, [clip], opts, on_frame=on_frame).run()
    assert tracker.error is None
    assert stats.inputs["track"].applied == published.sent >= 5
    last = parse_line(published.stream.getvalue().splitlines()[-1])
    np.testing.assert_allclose(drawn[-1], last.eye, atol=1e-9)  # type: ignore[union-attr]


def test_play_with_a_bad_track_camera_is_exit_2(tmp_path: Path, capsys):
    from tests.support.calibrations import small_calibration

    cal = small_calibration(64, 32, screen="magenta")
    plain, tracked = tmp_path / "plain.vcb", tmp_path / "tracked.vcb"
    # a rig without [tracker] (a bundle from before simulate wrote one): its camera faces the
    # screen
    replace(cal, rig=replace(cal.rig, tracker=None)).save(plain)
    replace(cal, rig=replace(cal.rig, tracker=walk_camera())).save(tracked)
    for bundle, says in ((plain, "add a [tracker] section"),
                         (tracked, "no such camera, file or folder")):  # fmt: skip
        code = main(["play", str(bundle), str(tmp_path / "clip.mp4"), "--track-camera",
                     str(tmp_path / "nothing")])  # fmt: skip
        assert code == 2
        err = capsys.readouterr().err
        assert err.startswith("viewcomp play: error: ") and says in err


def test_nearest_keeps_a_viewer_through_a_missed_frame():
    """Two viewers 0.2 m apart in distance: a frame that misses the followed one keeps its
    (held) eye instead of jumping to the other; a viewer nearer by more than the margin
    takes over at once."""
    tr = EyeTracker(TrackerConfig(hold=1.0, switch_margin=0.3))
    a, b = np.array([0.3, 0.1, 1.5]), np.array([-0.5, 0.1, 1.6])
    box = np.array([100.0, 100.0, 50.0, 50.0])
    both = np.stack([a, b])
    boxes = np.stack([box, box + np.array([300.0, 0, 0, 0])])
    np.testing.assert_array_equal(tr.update(both, boxes, 0.0)[0], a)
    np.testing.assert_array_equal(tr.update(b[None], boxes[1:], 0.1)[0], a)  # a missed: held
    np.testing.assert_array_equal(tr.update(both, boxes, 0.2)[0], a)
    near = np.array([0.0, 0.1, 0.9])  # nearer than a by 0.6 m
    got = tr.update(
        np.stack([a, b, near]), np.stack([*boxes, box + np.array([600.0, 0, 0, 0])]), 0.3
    )
    np.testing.assert_array_equal(got[0], near)
    # everyone gone: after the hold, the followed eye eases to the default
    gone = tr.update(np.zeros((0, 3)), np.zeros((0, 4)), 0.3 + 1.0 + 0.5)
    assert 0 < np.linalg.norm(gone[0] - near) < np.linalg.norm(np.array((0.0, 0.0, 2.0)) - near)
