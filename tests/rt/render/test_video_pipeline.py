"""render_file on videos and images: round trips, errors, angle tracks, soak."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import av
import cv2
import numpy as np
import pytest

from tests.support.synthetic import (
    SyntheticCompensation,
    make_compensation,
    make_test_video,
    smooth_frame,
    synthetic_model,
)
from viewcomp.calib.comp.compensation import thumbnail
from viewcomp.calib.model.reference import compensate
from viewcomp.calib.world.eye import eye_from_angle
from viewcomp.rt.gl.context import GLUnavailable, live_gl_objects
from viewcomp.rt.media.frames import fit_rgb
from viewcomp.rt.media.video import VideoError, VideoReader
from viewcomp.rt.render.pipeline import ImageError, render_file
from viewcomp.rt.render.tracks import AngleTrack, TrackError, constant_angle, load_angle_track

W, H = 192, 108


def probe(path: Path) -> tuple[int, float, float]:
    """(video frames decoded, average fps, audio seconds decoded) of a file."""
    with av.open(str(path)) as c:
        rate = float(c.streams.video[0].average_rate)
        frames = sum(1 for _ in c.decode(video=0))
    with av.open(str(path)) as c:
        if not c.streams.audio:
            return frames, rate, 0.0
        samples = sum(f.samples for f in c.decode(audio=0))
        sr = c.streams.audio[0].codec_context.sample_rate
    return frames, rate, samples / sr


def decode_rgb(path: Path) -> list[np.ndarray]:
    with av.open(str(path)) as c:
        return [f.to_ndarray(format="rgb24") for f in c.decode(video=0)]


@pytest.fixture(scope="module")
def clip(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("clip") / "in.mp4"
    make_test_video(str(path), 320, 180, seconds=2.0, rate=25, audio=True)
    return path


@pytest.fixture(scope="module")
def clip5(tmp_path_factory) -> Path:
    """A clip of 5 seconds, 320x160 at 25 fps, a 440 Hz tone (AAC)."""
    path = tmp_path_factory.mktemp("clip5") / "five.mp4"
    make_test_video(str(path), 320, 160, seconds=5.0, rate=25, audio=True)
    return path


def fake(method: str = "pixel", w: int = W, h: int = H, **kw) -> SyntheticCompensation:
    return SyntheticCompensation(synthetic_model(method, w, h), **kw)  # type: ignore[arg-type]


def only(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


@pytest.mark.gl
@pytest.mark.parametrize("identity", [False, True])
def test_five_second_clip_keeps_frames_rate_audio(gl_ctx, clip5, tmp_path, identity) -> None:
    comp = make_compensation("pixel", 64, 32, tau=0.5)
    out = tmp_path / "out.mp4"
    stats = render_file(comp, clip5, out, constant_angle(60, 0.5, 0.035), identity=identity,
                        progress=False, ctx=gl_ctx)  # fmt: skip
    frames, rate, audio = probe(out)
    assert abs(stats.frames - 125) <= 1 and abs(frames - 125) <= 1
    assert rate == pytest.approx(25.0)
    assert audio == pytest.approx(5.0, abs=0.1)
    with av.open(str(out)) as c:
        assert c.streams.video[0].codec_context.name == "h264"
        assert (c.streams.video[0].width, c.streams.video[0].height) == (64, 32)
    assert only(tmp_path) == ["out.mp4"]
    if identity:
        assert getattr(comp, "calls", 0) == 0


@pytest.mark.gl
def test_comp_called_once_per_frame_with_its_time(gl_ctx, clip, tmp_path) -> None:
    comp = fake("pixel")
    stats = render_file(comp, clip, tmp_path / "o.mkv", constant_angle(60, 0.5, 0.035),
                        progress=False, ctx=gl_ctx)  # fmt: skip
    assert stats.frames == comp.calls == 50
    assert comp.times == pytest.approx([i / 25 for i in range(50)], abs=1e-6)
    assert comp.thumb_shape is not None and max(comp.thumb_shape[:2]) <= 96
    # the time spent choosing parameters and to the first frame: bench/bench_render.py prints
    # them (a time is not asserted on a shared machine)


@pytest.mark.gl
def test_gl_equals_cpu_backend_with_angle_track(gl_ctx, clip, tmp_path) -> None:
    """Paper method, a new model per eye (update_model every frame), lossless output."""
    track = AngleTrack(np.array([0.0, 2.0]), np.array([50.0, 130.0]), 0.5, 0.035)
    outs = {}
    for backend in ("gl", "cpu"):
        comp = fake("paper", 96, 54, eye_dependent=True)
        outs[backend] = tmp_path / f"{backend}.mkv"
        render_file(comp, clip, outs[backend], track, backend=backend, crf=0, progress=False,
                    ctx=gl_ctx)  # fmt: skip
        assert len(comp._cache) > 40  # the model changed with the eye
    gl, cpu = decode_rgb(outs["gl"]), decode_rgb(outs["cpu"])
    assert len(gl) == len(cpu) == 50
    d = np.abs(np.stack(gl).astype(int) - np.stack(cpu))
    assert d.max() <= 3 and np.mean(d > 1) <= 0.001


@pytest.mark.gl
def test_audio_transcoded_when_container_cannot_take_it(gl_ctx, tmp_path) -> None:
    src = tmp_path / "in.mkv"
    make_test_video(str(src), 64, 48, seconds=1.0, rate=10, audio_codec="pcm_s16le")
    out = tmp_path / "out.mp4"
    render_file(fake("paper", 64, 48), src, out, constant_angle(90, 0.5, 0.0), progress=False,
                ctx=gl_ctx)  # fmt: skip
    with av.open(str(out)) as c:
        assert c.streams.audio[0].codec_context.name == "aac"
    frames, rate, audio = probe(out)
    assert (frames, rate) == (10, 10.0)
    assert audio == pytest.approx(1.0, abs=0.1)


def test_cpu_backend_video(clip, tmp_path) -> None:
    out = tmp_path / "cpu.mkv"
    stats = render_file(fake("paper", 96, 54), clip, out, constant_angle(70, 0.5, 0.035),
                        backend="cpu", progress=False)  # fmt: skip
    assert stats.frames == 50
    assert probe(out)[0] == 50


def test_encoder_preset_and_bad_preset(clip, tmp_path) -> None:
    out = tmp_path / "p.mp4"
    render_file(fake("paper", 64, 36), clip, out, constant_angle(90, 0.5, 0.0), backend="cpu",
                preset="ultrafast", progress=False)  # fmt: skip
    assert probe(out)[0] == 50
    with pytest.raises(VideoError, match=r"unknown preset 'warp'.*fix: use one of"):
        render_file(fake("paper", 64, 36), clip, tmp_path / "q.mp4",
                    constant_angle(90, 0.5, 0.0), backend="cpu", preset="warp",
                    progress=False)  # fmt: skip
    assert only(tmp_path) == ["p.mp4"]


def test_reader_fits_frames_to_grid(clip) -> None:
    with VideoReader(clip, fit=(100, 100), audio="none") as reader:
        planes = next(p for p in reader)
    assert planes.shape == (100, 100)
    assert planes.u.shape == (50, 50)
    assert (planes.y[:20] == 16).all() and (planes.y[-20:] == 16).all()  # letterbox, black
    assert planes.colorspace == "bt601" and planes.color_range == "limited"


@pytest.mark.parametrize("backend", ["cpu", pytest.param("gl", marks=pytest.mark.gl)])
def test_unreadable_video_is_one_clear_error(tmp_path, backend, request) -> None:
    ctx = request.getfixturevalue("gl_ctx") if backend == "gl" else None
    bad = tmp_path / "broken.mp4"
    bad.write_bytes(b"\x00\x00\x00\x18ftypmp42" + bytes(range(256)) * 8)
    out = tmp_path / "out.mp4"
    with pytest.raises(VideoError) as info:
        render_file(fake("paper", 32, 32), bad, out, constant_angle(90, 0.5, 0.0),
                    backend=backend, progress=False, ctx=ctx)  # fmt: skip
    msg = str(info.value)
    assert msg.startswith(f"cannot read video {bad}") and "fix: " in msg and "ffmpeg -i" in msg
    assert only(tmp_path) == ["broken.mp4"]


def test_truncated_video_leaves_no_output(clip, tmp_path) -> None:
    cut = tmp_path / "cut.mp4"
    data = clip.read_bytes()
    cut.write_bytes(data[: len(data) // 3])  # the index (moov) is at the end: unreadable
    out = tmp_path / "out.mp4"
    with pytest.raises(VideoError, match=r"cut\.mp4.*fix:"):
        render_file(fake("paper", 32, 32), cut, out, constant_angle(90, 0.5, 0.0),
                    backend="cpu", progress=False)  # fmt: skip
    assert only(tmp_path) == ["cut.mp4"]


def test_failing_comp_leaves_no_output(clip, tmp_path) -> None:
    calls = []

    def tone(thumb):
        calls.append(1)
        if len(calls) == 10:
            raise RuntimeError("tone map failed")
        return 0.5, 0.0

    with pytest.raises(RuntimeError, match="tone map failed"):
        render_file(fake("paper", 32, 32, tone=tone), clip, tmp_path / "o.mp4",
                    constant_angle(90, 0.5, 0.0), backend="cpu", progress=False)  # fmt: skip
    assert only(tmp_path) == []


def test_comp_must_look_like_a_compensation(clip, tmp_path) -> None:
    with pytest.raises(TypeError, match=r"comp must be a viewcomp.calib.comp.compensation"):
        render_file(synthetic_model("paper", 8, 8), clip, tmp_path / "o.mp4",  # type: ignore[arg-type]
                    constant_angle(90, 0.5, 0.0), backend="cpu", progress=False)  # fmt: skip
    comp = fake("paper", 16, 8)
    comp.method = "pixel"
    with pytest.raises(ValueError, match=r"comp says pixel on \(8, 16\) but its base model"):
        render_file(comp, clip, tmp_path / "o.mp4", constant_angle(90, 0.5, 0.0),
                    backend="cpu", progress=False)  # fmt: skip
    assert only(tmp_path) == []


@pytest.mark.gl
@pytest.mark.parametrize("backend", ["gl", "cpu"])
def test_image_round_trip(gl_ctx, tmp_path, backend) -> None:
    model = synthetic_model("pixel", W, H)
    src = smooth_frame(300, 200, seed=8)
    cv2.imwrite(str(tmp_path / "in.png"), cv2.cvtColor(src, cv2.COLOR_RGB2BGR))
    out = tmp_path / "out.png"
    comp = SyntheticCompensation(model, tone=lambda t: (0.5 + t.mean() / 2550, 0.02))
    render_file(comp, tmp_path / "in.png", out, constant_angle(120, 0.5, 0.035),
                backend=backend, progress=False, ctx=gl_ctx)  # fmt: skip
    got = cv2.cvtColor(cv2.imread(str(out), cv2.IMREAD_UNCHANGED), cv2.COLOR_BGR2RGB)
    fitted = fit_rgb(src, W, H)
    assert comp.times == [None] and comp.thumb_shape == thumbnail(fitted).shape
    alpha = 0.5 + thumbnail(fitted).mean() / 2550
    ref = compensate(model, fitted, eye_from_angle(120, 0.5, 0.035), alpha, 0.02)
    d = np.abs(got.astype(int) - ref)
    assert got.shape == (H, W, 3) and d.max() <= 3 and np.mean(d > 1) <= 0.001


def test_unreadable_image(tmp_path) -> None:
    (tmp_path / "x.png").write_bytes(b"not a png")
    with pytest.raises(ImageError, match="cannot read image"):
        render_file(fake("paper", 8, 8), tmp_path / "x.png", tmp_path / "o.png",
                    constant_angle(90, 0.5, 0.0), backend="cpu", progress=False)  # fmt: skip
    assert not (tmp_path / "o.png").exists()


def test_missing_egl_is_one_clear_error(monkeypatch, tmp_path) -> None:
    """create_context failing (monkeypatched) -> GLUnavailable with the fix, no output."""
    import moderngl

    def no_egl(*args, **kwargs):
        raise Exception("libEGL.so.1: cannot open shared object file")  # what glcontext says

    monkeypatch.setattr(moderngl, "create_standalone_context", no_egl)
    cv2.imwrite(str(tmp_path / "in.png"), np.zeros((8, 8, 3), np.uint8))
    with pytest.raises(GLUnavailable) as info:
        render_file(fake("pixel", 8, 8), tmp_path / "in.png", tmp_path / "out.png",
                    constant_angle(90, 0.5, 0.0), progress=False)  # fmt: skip
    msg = str(info.value)
    assert "cannot create an OpenGL 3.3 context through EGL" in msg and "libEGL.so.1" in msg
    assert "fix: install the Debian packages libegl1" in msg
    assert only(tmp_path) == ["in.png"]


def test_missing_egl_driver_in_a_subprocess(tmp_path) -> None:
    """A real driver-less EGL (libglvnd finds no vendor) gives the same single message."""
    cv2.imwrite(str(tmp_path / "in.png"), np.zeros((8, 8, 3), np.uint8))
    code = (
        "import sys\n"
        "from viewcomp.rt.render.pipeline import render_file\n"
        "from tests.support.synthetic import SyntheticCompensation, synthetic_model\n"
        "from viewcomp.rt.render.tracks import constant_angle\n"
        "from viewcomp.rt.gl.context import GLUnavailable\n"
        "try:\n"
        "    render_file(SyntheticCompensation(synthetic_model('pixel', 8, 8)),\n"
        f"                {str(tmp_path / 'in.png')!r}, {str(tmp_path / 'out.png')!r},\n"
        "                constant_angle(90, 0.5, 0.0), progress=False)\n"
        "except GLUnavailable as e:\n"
        "    print(e); sys.exit(3)\n"
    )
    env = {**os.environ, "__EGL_VENDOR_LIBRARY_FILENAMES": str(tmp_path / "none.json")}
    res = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         timeout=60)  # fmt: skip
    assert res.returncode == 3, res.stdout + res.stderr
    assert "cannot create an OpenGL 3.3 context through EGL" in res.stdout
    assert "fix: install the Debian packages" in res.stdout
    assert only(tmp_path) == ["in.png"]


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
        return int(f.read().split()[1]) * os.sysconf("SC_PAGESIZE") // 1024


class _SoakTrack:
    """A new angle every frame (45..134 degrees, cycling); samples GL objects and RSS."""

    def __init__(self, ctx, rate: float, warm: int = 200, end: int = 1999) -> None:
        self.ctx, self.rate, self.warm, self.end = ctx, rate, warm, end
        self.samples: dict[str, tuple[dict[str, int], int]] = {}
        self.last = -1

    def __call__(self, t: float) -> np.ndarray:
        i = round(t * self.rate)
        for name, at in (("warm", self.warm), ("end", self.end)):
            if i == at and name not in self.samples:
                self.samples[name] = (live_gl_objects(self.ctx), _rss_kib())
        self.last = max(self.last, i)
        return eye_from_angle(45 + i % 90, 0.5, 0.035)


@pytest.mark.gl
@pytest.mark.slow
@pytest.mark.parametrize("method", ["pixel", "paper"])
def test_soak_2000_frames_through_the_pipeline(gl_ctx, tmp_path_factory, method) -> None:
    """2,000 frames, the angle changing every frame (paper: a new model each frame)."""
    src = tmp_path_factory.getbasetemp() / "soak.mp4"
    if not src.exists():
        make_test_video(str(src), 128, 72, seconds=80.0, rate=25, audio=True)
    comp = fake(method, 128, 72, eye_dependent=True,
                tone=lambda t: (0.5 + t.mean() / 5000, 0.01))  # fmt: skip
    track = _SoakTrack(gl_ctx, 25.0)
    out = tmp_path_factory.mktemp("soak") / "out.mp4"
    stats = render_file(comp, src, out, track, progress=False, ctx=gl_ctx)
    assert stats.frames == 2000 and track.last == 1999
    (objects0, rss0), (objects1, rss1) = track.samples["warm"], track.samples["end"]
    assert objects1 == objects0  # counted by the driver (glIs*), frame 200 vs frame 1999
    assert rss1 <= rss0 * 1.05, (rss0, rss1)
    after = live_gl_objects(gl_ctx)  # the compensator is gone: nothing left behind
    assert all(after[k] <= objects0[k] for k in after) and sum(after.values()) < sum(
        objects0.values()
    )
