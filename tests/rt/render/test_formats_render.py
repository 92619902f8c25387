"""A 10-second clip with audio rendered to every output format, then played back.

Each output is decoded again with PyAV (or OpenCV for image files): codec, pixel format,
frame count and audio length checked. Tiny frames (64x32; 256x128 for DNxHR, its minimum)
and the CPU backend keep it fast: the writers, not the compensation, are under test.
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import av
import cv2
import numpy as np
import pytest

from tests.support.synthetic import SyntheticCompensation, make_test_video, synthetic_model
from viewcomp.rt.media.formats import ffmpeg_encoders
from viewcomp.rt.render.pipeline import render_file
from viewcomp.rt.render.tracks import constant_angle

SECONDS, RATE = 10.0, 10
FRAMES = round(SECONDS * RATE)
EYE = constant_angle(60, 0.5, 0.035)


def fake(w: int = 64, h: int = 32, **kw) -> SyntheticCompensation:
    return SyntheticCompensation(synthetic_model("paper", w, h), **kw)


@pytest.fixture(scope="module")
def clip(tmp_path_factory) -> Path:
    """10 s at 10 fps, 64x32 H.264, a 440 Hz tone in AAC at 44.1 kHz (Opus needs 48 kHz:
    the re-encode resamples)."""
    path = tmp_path_factory.mktemp("clip") / "ten.mp4"
    make_test_video(str(path), 64, 32, seconds=SECONDS, rate=RATE, sample_rate=44100)
    return path


def playback(path: Path) -> dict[str, object]:
    """What a player sees: codec, pixel format, size, frames decoded, audio codec and
    seconds of audio decoded."""
    with av.open(str(path)) as c:
        v = c.streams.video[0]
        info: dict[str, object] = {
            "codec": v.codec_context.name,
            "pix_fmt": v.codec_context.format.name if v.codec_context.format else None,
            "size": (v.codec_context.width, v.codec_context.height),
            "rate": float(v.average_rate) if v.average_rate else None,
            "frames": sum(1 for _ in c.decode(video=0)),
        }
    with av.open(str(path)) as c:
        if c.streams.audio:
            a = c.streams.audio[0]
            info["audio"] = a.codec_context.name
            info["audio_s"] = sum(f.samples for f in c.decode(audio=0)) / a.codec_context.rate
        else:
            info["audio"], info["audio_s"] = None, 0.0
    return info


def names(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


# (output name, --codec, --profile, decoded codec, decoded pixel format, audio codec)
FORMATS = [
    ("h264.mp4", None, None, "h264", "yuv420p", "aac"),
    ("h265.mp4", "libx265", None, "hevc", "yuv420p", "aac"),
    ("h264.mkv", None, None, "h264", "yuv420p", "aac"),
    ("h265.mkv", "hevc", None, "hevc", "yuv420p", "aac"),
    ("prores.mov", "prores_ks", None, "prores", "yuv422p10le", "aac"),
    ("prores_lt.mov", "prores", "lt", "prores", "yuv422p10le", "aac"),
    ("vp9.webm", None, None, "vp9", "yuv420p", "opus"),
    ("av1.webm", "libsvtav1", None, None, "yuv420p", "opus"),
    ("vp9.mkv", "vp9", None, "vp9", "yuv420p", "aac"),
    ("av1.mkv", "av1", None, None, "yuv420p", "aac"),
    ("ffv1.mkv", "ffv1", None, "ffv1", "yuv444p", "aac"),
]


@pytest.mark.parametrize(("name", "codec", "profile", "decoded", "pix_fmt", "audio"), FORMATS)
def test_clip_renders_and_plays_back(clip, tmp_path, name, codec, profile, decoded, pix_fmt,
                                     audio) -> None:  # fmt: skip
    out = tmp_path / name
    stats = render_file(fake(), clip, out, EYE, backend="cpu", codec=codec, profile=profile,
                        progress=False)  # fmt: skip
    got = playback(out)
    assert stats.frames == FRAMES and got["frames"] == FRAMES
    if decoded is not None:  # AV1's decoder is named after the library (libdav1d, libaom)
        assert got["codec"] == decoded
    assert got["pix_fmt"] == pix_fmt and got["size"] == (64, 32)
    assert got["rate"] == pytest.approx(RATE)
    assert got["audio"] == audio
    assert got["audio_s"] == pytest.approx(SECONDS, abs=0.1)
    assert names(tmp_path) == [name]  # no temporary file left next to it


def test_dnxhr_at_its_minimum_size(clip, tmp_path) -> None:
    out = tmp_path / "dnxhr.mov"
    render_file(fake(256, 128), clip, out, EYE, backend="cpu", codec="dnxhd", progress=False)
    got = playback(out)
    assert (got["codec"], got["pix_fmt"], got["size"]) == ("dnxhd", "yuv422p", (256, 128))
    assert got["frames"] == FRAMES and got["audio"] == "aac"
    assert got["audio_s"] == pytest.approx(SECONDS, abs=0.1)


def _has_hap() -> bool:
    encoders = ffmpeg_encoders()
    return encoders is not None and "hap" in encoders


needs_hap = pytest.mark.skipif(
    not _has_hap(),
    reason="no ffmpeg program with the hap encoder on PATH "
    "(`ffmpeg -hide_banner -encoders | grep hap`): HAP goes through it",
)


@needs_hap
@pytest.mark.parametrize("profile", [None, "hap_q"])
def test_hap_through_the_ffmpeg_program(clip, tmp_path, profile) -> None:
    out = tmp_path / "hap.mov"
    render_file(fake(), clip, out, EYE, backend="cpu", codec="hap", profile=profile,
                progress=False)  # fmt: skip
    got = playback(out)
    assert got["codec"] == "hap" and got["size"] == (64, 32) and got["frames"] == FRAMES
    assert got["audio"] == "aac"  # copied from the input (.mov takes AAC)
    assert got["audio_s"] == pytest.approx(SECONDS, abs=0.1)
    assert names(tmp_path) == ["hap.mov"]
    with av.open(str(out)) as c:
        tag = c.streams.video[0].codec_context.codec_tag
    assert tag == ("HapY" if profile == "hap_q" else "Hap1")  # HAP Q's fourcc is HapY


@needs_hap
def test_hap_failure_leaves_nothing(clip, tmp_path) -> None:
    calls = []

    def tone(thumb):
        calls.append(1)
        if len(calls) == 30:
            raise RuntimeError("tone map failed")
        return 0.5, 0.0

    with pytest.raises(RuntimeError, match="tone map failed"):
        render_file(fake(tone=tone), clip, tmp_path / "hap.mov", EYE, backend="cpu",
                    codec="hap", progress=False)  # fmt: skip
    assert names(tmp_path) == []


@pytest.mark.parametrize("suffix", [".png", ".jpg", ".tif"])
def test_image_sequence(clip, tmp_path, suffix) -> None:
    pattern = tmp_path / "frames" / f"%05d{suffix}"
    stats = render_file(fake(), clip, pattern, EYE, backend="cpu", progress=False)
    files = names(tmp_path / "frames")
    assert stats.frames == FRAMES
    assert files == [f"{i:05d}{suffix}" for i in range(FRAMES)]  # numbered from 0
    assert names(tmp_path) == ["frames"]  # the temporary folder is gone
    first = cv2.imread(str(tmp_path / "frames" / files[0]), cv2.IMREAD_UNCHANGED)
    assert first.shape == (32, 64, 3) and first.dtype == np.uint8


def test_image_sequence_matches_the_lossless_video(clip, tmp_path) -> None:
    """The PNG frames are the renderer's RGB exactly: equal to a PNG still of the same frame
    would be, and close to the FFV1 (4:4:4) video's decoded frames."""
    render_file(fake(), clip, tmp_path / "f" / "%03d.png", EYE, backend="cpu", progress=False)
    render_file(fake(), clip, tmp_path / "v.mkv", EYE, backend="cpu", codec="ffv1",
                progress=False)  # fmt: skip
    with av.open(str(tmp_path / "v.mkv")) as c:
        video = [f.to_ndarray(format="rgb24") for f in c.decode(video=0)]
    for i in (0, 50, 99):
        png = cv2.imread(str(tmp_path / "f" / f"{i:03d}.png"))[:, :, ::-1]
        assert np.abs(png.astype(int) - video[i]).max() <= 3  # the YUV round trip only


def test_image_sequence_failure_leaves_nothing(clip, tmp_path) -> None:
    calls = []

    def tone(thumb):
        calls.append(1)
        if len(calls) == 30:
            raise RuntimeError("tone map failed")
        return 0.5, 0.0

    with pytest.raises(RuntimeError, match="tone map failed"):
        render_file(fake(tone=tone), clip, tmp_path / "frames" / "%05d.png", EYE,
                    backend="cpu", progress=False)  # fmt: skip
    assert names(tmp_path) == []


@pytest.mark.parametrize("name", ["still.jpg", "still.jpeg", "still.tif", "still.tiff"])
def test_stills(tmp_path, name) -> None:
    rng = np.random.default_rng(3)
    src = tmp_path / "in.png"
    cv2.imwrite(str(src), rng.integers(0, 256, (32, 64, 3), np.uint8))
    render_file(fake(), src, tmp_path / "ref.png", EYE, backend="cpu", progress=False)
    render_file(fake(), src, tmp_path / name, EYE, backend="cpu", progress=False)
    ref = cv2.imread(str(tmp_path / "ref.png"), cv2.IMREAD_UNCHANGED)
    got = cv2.imread(str(tmp_path / name), cv2.IMREAD_UNCHANGED)
    assert got.shape == ref.shape == (32, 64, 3) and got.dtype == np.uint8
    if name.endswith((".tif", ".tiff")):
        assert np.array_equal(got, ref)  # lossless
    else:
        assert np.abs(got.astype(int) - ref).mean() < 4  # JPEG quality 95, 4:4:4
    assert names(tmp_path) == sorted(["in.png", "ref.png", name])


@needs_hap
def test_hap_keeps_sync_like_the_pyav_writer(clip, tmp_path) -> None:
    """Video starting 0.5 s after the audio: ffmpeg (HAP) and PyAV (H.264) shift the audio
    the same way, so both outputs hold the same audio, starting with the first frame."""
    late = tmp_path / "late.mkv"
    ffmpeg = shutil.which("ffmpeg")
    assert ffmpeg is not None
    subprocess.run([ffmpeg, "-v", "error", "-i", str(clip), "-itsoffset", "0.5", "-i",
                    str(clip), "-map", "1:v", "-map", "0:a", "-c", "copy", str(late)],
                   check=True, timeout=60)  # fmt: skip
    got = {}
    for name, codec in (("h264.mov", None), ("hap.mov", "hap")):
        render_file(fake(), late, tmp_path / name, EYE, backend="cpu", codec=codec,
                    progress=False)  # fmt: skip
        got[name] = playback(tmp_path / name)
    assert got["hap.mov"]["frames"] == got["h264.mov"]["frames"] == FRAMES
    assert got["h264.mov"]["audio_s"] == pytest.approx(SECONDS - 0.5, abs=0.1)
    assert got["hap.mov"]["audio_s"] == pytest.approx(got["h264.mov"]["audio_s"], abs=0.03)
