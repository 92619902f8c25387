"""Video/image round trips through render_file, errors, angle tracks, and a soak test."""

from __future__ import annotations

import resource
from pathlib import Path

import av
import cv2
import numpy as np
import pytest

from viewcomp.calib.reference import compensate
from viewcomp.rt.compensator import Compensator, eye_from_angle
from viewcomp.rt.context import live_gl_objects
from viewcomp.rt.frames import fit_rgb, rgb_to_yuv420p
from viewcomp.rt.pipeline import ImageError, render_file
from viewcomp.rt.testing import make_test_video, smooth_frame, synthetic_model
from viewcomp.rt.tracks import TrackError, constant_angle, load_angle_track
from viewcomp.rt.video import VideoError, VideoReader

W, H = 192, 108


def probe(path: Path) -> tuple[int, float, float]:
    """(video frames decoded, average fps, audio seconds decoded) of a file."""
    with av.open(str(path)) as c:
        rate = float(c.streams.video[0].average_rate)
        frames = sum(1 for _ in c.decode(video=0))
    with av.open(str(path)) as c:
        samples = sum(f.samples for f in c.decode(audio=0))
        sr = c.streams.audio[0].codec_context.sample_rate
    return frames, rate, samples / sr


@pytest.fixture(scope="module")
def clip(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("clip") / "in.mp4"
    make_test_video(str(path), 320, 180, seconds=2.0, rate=25, audio=True)
    return path


@pytest.mark.gl
@pytest.mark.parametrize("identity", [True, False])
def test_video_round_trip_keeps_frames_rate_audio(gl_ctx, clip, tmp_path, identity) -> None:
    model = synthetic_model("pixel", W, H)
    out = tmp_path / "out.mp4"
    stats = render_file(
        model, clip, out, constant_angle(60, 0.5, 0.035), identity=identity, progress=False,
        tone=lambda thumb: (0.55, 0.02), ctx=gl_ctx,
    )  # fmt: skip
    assert stats.frames == 50
    frames, rate, audio = probe(out)
    assert frames == 50
    assert rate == pytest.approx(25.0)
    assert audio == pytest.approx(2.0, abs=0.1)
    with av.open(str(out)) as c:
        assert c.streams.video[0].codec_context.name == "h264"
        assert (c.streams.video[0].width, c.streams.video[0].height) == (W, H)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.mp4"]


@pytest.mark.gl
def test_audio_transcoded_when_container_cannot_take_it(gl_ctx, tmp_path) -> None:
    src = tmp_path / "in.mkv"
    make_test_video(str(src), 64, 48, seconds=1.0, rate=10, audio_codec="pcm_s16le")
    out = tmp_path / "out.mp4"
    render_file(synthetic_model("paper", 64, 48), src, out, constant_angle(90, 0.5, 0.0),
                progress=False, ctx=gl_ctx)  # fmt: skip
    with av.open(str(out)) as c:
        assert c.streams.audio[0].codec_context.name == "aac"
    frames, rate, audio = probe(out)
    assert (frames, rate) == (10, 10.0)
    assert audio == pytest.approx(1.0, abs=0.1)


def test_cpu_backend_video(clip, tmp_path) -> None:
    out = tmp_path / "cpu.mkv"
    stats = render_file(synthetic_model("paper", 96, 54), clip, out,
                        constant_angle(70, 0.5, 0.035), backend="cpu", progress=False)  # fmt: skip
    assert stats.frames == 50
    assert probe(out)[0] == 50


def test_reader_fits_frames_to_grid(clip) -> None:
    with VideoReader(clip, fit=(100, 100), audio="none") as reader:
        planes = next(p for p in reader)
    assert planes.shape == (100, 100)
    assert planes.u.shape == (50, 50)
    assert (planes.y[:20] == 16).all() and (planes.y[-20:] == 16).all()  # letterbox, black
    assert planes.colorspace == "bt601" and planes.color_range == "limited"


def test_unreadable_video_is_one_clear_error(tmp_path) -> None:
    bad = tmp_path / "broken.mp4"
    bad.write_bytes(b"\x00\x00\x00\x18ftypmp42" + bytes(range(256)) * 8)
    out = tmp_path / "out.mp4"
    with pytest.raises(VideoError, match=r"cannot read video .*broken\.mp4.*fix:"):
        render_file(synthetic_model("paper", 32, 32), bad, out, constant_angle(90, 0.5, 0.0),
                    backend="cpu", progress=False)  # fmt: skip
    assert sorted(p.name for p in tmp_path.iterdir()) == ["broken.mp4"]


def test_truncated_video_leaves_no_output(clip, tmp_path) -> None:
    cut = tmp_path / "cut.mp4"
    data = clip.read_bytes()
    cut.write_bytes(data[: len(data) // 3])  # the index (moov) is at the end: unreadable
    out = tmp_path / "out.mp4"
    with pytest.raises(VideoError):
        render_file(synthetic_model("paper", 32, 32), cut, out, constant_angle(90, 0.5, 0.0),
                    backend="cpu", progress=False)  # fmt: skip
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cut.mp4"]


@pytest.mark.gl
@pytest.mark.parametrize("backend", ["gl", "cpu"])
def test_image_round_trip(gl_ctx, tmp_path, backend) -> None:
    model = synthetic_model("pixel", W, H)
    src = smooth_frame(300, 200, seed=8)
    cv2.imwrite(str(tmp_path / "in.png"), cv2.cvtColor(src, cv2.COLOR_RGB2BGR))
    out = tmp_path / "out.png"
    render_file(model, tmp_path / "in.png", out, constant_angle(120, 0.5, 0.035),
                backend=backend, progress=False, tone=lambda t: (0.55, 0.02),
                ctx=gl_ctx)  # fmt: skip
    got = cv2.cvtColor(cv2.imread(str(out), cv2.IMREAD_UNCHANGED), cv2.COLOR_BGR2RGB)
    ref = compensate(model, fit_rgb(src, W, H), eye_from_angle(120, 0.5, 0.035), 0.55, 0.02)
    d = np.abs(got.astype(int) - ref)
    assert got.shape == (H, W, 3) and d.max() <= 3 and np.mean(d > 1) <= 0.001


def test_unreadable_image(tmp_path) -> None:
    (tmp_path / "x.png").write_bytes(b"not a png")
    with pytest.raises(ImageError, match="cannot read image"):
        render_file(synthetic_model("paper", 8, 8), tmp_path / "x.png", tmp_path / "o.png",
                    constant_angle(90, 0.5, 0.0), backend="cpu", progress=False)  # fmt: skip
    assert not (tmp_path / "o.png").exists()


def test_angle_track_csv(tmp_path) -> None:
    p = tmp_path / "track.csv"
    p.write_text("seconds,degrees\n0,60\n# comment\n\n2,120\n")
    track = load_angle_track(p, 0.5, 0.035)
    assert track.angle(1.0) == pytest.approx(90.0)
    assert track.angle(-1) == 60.0 and track.angle(5) == 120.0
    np.testing.assert_allclose(track(1.0), eye_from_angle(90, 0.5, 0.035), atol=1e-6)


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("0,60\n1\n", r"track.csv:2: expected 2 columns"),
        ("0,60\n1,abc\n", r"track.csv:2: not a number"),
        ("0,60\n0,70\n", r"track.csv:2: time 0.0 is not after 0.0"),
        ("seconds,degrees\n", "no \\(seconds, degrees\\) rows"),
    ],
)
def test_malformed_track_csv(tmp_path, text, match) -> None:
    p = tmp_path / "track.csv"
    p.write_text(text)
    with pytest.raises(TrackError, match=match):
        load_angle_track(p, 0.5, 0.035)


def _rss_kib() -> int:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * resource.getpagesize() // 1024


@pytest.mark.gl
def test_soak_angle_changes_every_frame(gl_ctx) -> None:
    """2,000 frames, a new eye and tone each frame: no GL object or memory growth."""
    w, h = 128, 72
    planes = rgb_to_yuv420p(smooth_frame(w, h))
    out = np.empty((h, w, 3), np.uint8)
    with Compensator(synthetic_model("pixel", w, h), gl_ctx) as comp:
        for i in range(2000):
            if i == 200:
                objects0, rss0 = live_gl_objects(gl_ctx), _rss_kib()
            comp.set_angle(45 + (i % 90), 0.5, 0.035)
            comp.set_tone(0.5 + 0.001 * (i % 50), 0.02)
            comp.identity = i % 7 == 0
            comp.render_planes(planes, out=out)
        assert live_gl_objects(gl_ctx) == objects0
        assert _rss_kib() <= rss0 * 1.05
