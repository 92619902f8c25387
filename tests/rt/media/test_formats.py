"""The output format table and its checks before any work (no rendering here).

Every unsupported extension/codec/profile pairing is refused with the list of the working
ones (exit status 2 on the command line) before the calibration is loaded or the input
opened; encoders missing from the build or unable to start are named as such; FFmpeg's
codes become plain causes.
"""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

import av
import numpy as np
import pytest

from tests.support.synthetic import SyntheticCompensation, make_test_video, synthetic_model
from viewcomp.rt.media import formats
from viewcomp.rt.media.averrors import describe_av_error, mp4_missing_index
from viewcomp.rt.media.formats import CONTAINERS, FormatError, plan_output
from viewcomp.rt.render.pipeline import render_file
from viewcomp.rt.render.tracks import constant_angle

PAIRINGS = "the working pairings: .mp4"


def fake(w: int = 64, h: int = 32) -> SyntheticCompensation:
    return SyntheticCompensation(synthetic_model("paper", w, h))


# (output, codec, profile, what the message says besides the pairings, or None)
REFUSED = [
    ("x.webm", "libx264", None, "a .webm file cannot hold 'libx264' video - libx264 goes in .mp4"),
    ("x.webm", "h264", None, "cannot hold 'libx264'"),  # an alias, resolved first
    ("x.mp4", "prores_ks", None, "prores_ks goes in .mov"),
    ("x.mp4", "ffv1", None, "ffv1 goes in .mkv"),
    ("x.mp4", "hap", None, "hap goes in .mov"),
    ("x.mov", "libvpx-vp9", None, "libvpx-vp9 goes in .mkv, .webm"),
    ("x.webm", "prores_ks", None, "cannot hold 'prores_ks'"),
    ("x.mkv", "mpeg2video", None, "cannot hold 'mpeg2video'"),
    ("x.avi", None, None, "unknown video extension '.avi'"),
    ("x.gif", None, None, "unknown video extension '.gif'"),
    ("x", None, None, "give a file name with its extension"),
]


@pytest.mark.parametrize(("out", "codec", "profile", "says"), REFUSED)
def test_unsupported_pairing_lists_the_working_ones(tmp_path, out, codec, profile, says) -> None:
    with pytest.raises(FormatError) as info:
        plan_output(tmp_path / out, False, codec, profile)
    msg = str(info.value)
    assert says in msg and PAIRINGS in msg
    for c in CONTAINERS:  # every container and its default named
        assert f"{'/'.join(c.extensions)}: " in msg and f"(default {c.codecs[0]})" in msg


@pytest.mark.parametrize(
    ("out", "codec", "profile", "says"),
    [
        ("x.mov", "prores_ks", "422", "Apple ProRes has no profile '422' - use one of hq, "),
        ("x.mov", "dnxhd", "dnxhr_hq", "Avid DNxHR has no profile 'dnxhr_hq'"),
        ("x.mp4", "libx264", "hq", "H.264 has no profile 'hq'"),
        ("x.mp4", None, None, None),  # no refusal: the control
    ],
)
def test_profile_must_be_the_codecs(tmp_path, out, codec, profile, says) -> None:
    if says is None:
        assert plan_output(tmp_path / out, False, codec, profile).codec is not None
        return
    with pytest.raises(FormatError, match=says):
        plan_output(tmp_path / out, False, codec, profile)


@pytest.mark.parametrize(
    ("out", "codec", "encoder", "pix_fmt", "depth", "audio"),
    [
        ("a.mp4", None, "libx264", "yuv420p", 8, "aac"),
        ("a.m4v", "hevc", "libx265", "yuv420p", 8, "aac"),
        ("a.mov", "prores", "prores_ks", "yuv422p10le", 10, "aac"),
        ("a.mov", "dnxhd", "dnxhd", "yuv422p", 8, "aac"),
        ("a.webm", None, "libvpx-vp9", "yuv420p", 8, "libopus"),
        ("a.webm", "av1", "libsvtav1", "yuv420p", 8, "libopus"),
        ("a.mkv", "ffv1", "ffv1", "yuv444p", 8, "libopus"),
    ],
)
def test_plan_gives_pixel_format_depth_and_audio(
    tmp_path, out, codec, encoder, pix_fmt, depth, audio
) -> None:
    plan = plan_output(tmp_path / out, False, codec)
    assert plan.codec is not None and plan.codec.encoder == encoder
    assert (plan.pix_fmt, plan.depth) == (pix_fmt, depth)
    assert plan.audio_plan("pcm_u8") == ("encode", audio)  # taken by none: re-encoded
    assert plan.audio_plan(None) is None


def test_audio_copied_when_the_container_takes_it(tmp_path) -> None:
    assert plan_output(tmp_path / "a.mp4", False).audio_plan("aac") == ("copy", "aac")
    assert plan_output(tmp_path / "a.mov", False).audio_plan("pcm_s16le")[0] == "copy"
    assert plan_output(tmp_path / "a.mkv", False).audio_plan("aac") == ("copy", "aac")
    assert plan_output(tmp_path / "a.webm", False).audio_plan("aac") == ("encode", "libopus")
    assert plan_output(tmp_path / "a.webm", False).audio_plan("opus") == ("copy", "opus")
    assert plan_output(tmp_path / "a.mp4", False).audio_plan("pcm_s16le") == ("encode", "aac")


def test_prores_profile_sets_pixel_format_and_option(tmp_path) -> None:
    hq = plan_output(tmp_path / "a.mov", False, "prores_ks")
    assert hq.profile == "hq" and hq.encoder_options(18, "veryfast") == {"profile": "3"}
    p4 = plan_output(tmp_path / "a.mov", False, "prores_ks", "4444")
    assert p4.pix_fmt == "yuv444p10le"
    x264 = plan_output(tmp_path / "a.mp4", False)
    assert x264.encoder_options(20, "slow") == {"crf": "20", "preset": "slow"}


@pytest.mark.parametrize(
    ("out", "image", "codec", "says"),
    [
        ("x.mp4", True, None, "an image renders to a .png, .jpg or .tif file"),
        ("x.bmp", True, None, "an image renders to a .png, .jpg or .tif file"),
        ("x.jpg", True, "prores", "--codec and --profile are for video files"),
        ("x.png", False, None, "a video renders to a video file or to an image sequence"),
        ("f/%05d.bmp", False, None, "an image sequence is .png, .jpg or .tif images"),
        ("f/%05d_%d.png", False, None, "one frame number in the file name"),
        ("f/%05d.png", False, "libx264", "--codec and --profile are for video files"),
    ],
)
def test_image_outputs_refused(tmp_path, out, image, codec, says) -> None:
    with pytest.raises(FormatError, match=says):
        plan_output(tmp_path / out, image, codec)


def test_sequence_folder_must_be_new_or_empty(tmp_path) -> None:
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "keep.txt").write_text("mine")
    with pytest.raises(FormatError, match="already holds files"):
        plan_output(tmp_path / "full" / "%05d.png", False)
    (tmp_path / "empty").mkdir()
    assert plan_output(tmp_path / "empty" / "%05d.tif", False).kind == "sequence"
    assert plan_output(tmp_path / "new" / "%d.jpg", False).kind == "sequence"
    (tmp_path / "file").write_text("x")
    with pytest.raises(FormatError, match="is a file"):
        plan_output(tmp_path / "file" / "%05d.png", False)


def test_stills(tmp_path) -> None:
    for name in ("a.png", "a.jpg", "a.JPEG", "a.tif", "a.tiff"):
        assert plan_output(tmp_path / name, True).kind == "still"


def _nvenc_opens() -> bool:
    try:
        cc = av.CodecContext.create("h264_nvenc", "w")
        cc.width, cc.height, cc.pix_fmt = 64, 32, "yuv420p"
        cc.time_base = Fraction(1, 25)
        cc.open()
    except (av.FFmpegError, ValueError, av.codec.codec.UnknownCodecError):
        return False
    return True


def test_hardware_encoder_that_cannot_start_is_named(tmp_path) -> None:
    if "h264_nvenc" not in av.codecs_available:
        pytest.skip("this FFmpeg build has no h264_nvenc")
    if _nvenc_opens():
        pytest.skip("this machine has a working NVIDIA encoder")
    plan = plan_output(tmp_path / "x.mp4", False, "h264_nvenc")  # in the build: planned
    with pytest.raises(FormatError) as info:
        plan.check_size(64, 32)
    msg = str(info.value)
    assert "'h264_nvenc' is in this FFmpeg build but it needs an NVIDIA GPU" in msg
    assert "permission" not in msg.lower() and "Errno" not in msg
    assert "--codec libx264" in msg


def test_encoder_missing_from_the_build_is_named(tmp_path, monkeypatch) -> None:
    monkeypatch.setattr(formats, "_pyav_has_encoder", lambda name: name != "libsvtav1")
    with pytest.raises(FormatError, match=r"the encoder 'libsvtav1' \(AV1\) is not in this FFmpeg"):
        plan_output(tmp_path / "x.webm", False, "av1")


@pytest.mark.parametrize(
    ("encoders", "says"),
    [(None, "there is none on PATH"), (frozenset({"prores_ks"}), "has no hap encoder")],
)
def test_hap_needs_the_ffmpeg_program_with_it(tmp_path, monkeypatch, encoders, says) -> None:
    monkeypatch.setattr(formats, "ffmpeg_encoders", lambda: encoders)
    with pytest.raises(FormatError, match=says):
        plan_output(tmp_path / "x.mov", False, "hap")


@pytest.mark.parametrize(
    ("codec", "w", "h", "says"),
    [("hap", 66, 32, "multiples of 4"), ("dnxhd", 64, 32, "at least 256x120")],
)
def test_grid_size_checked_against_the_codec(tmp_path, monkeypatch, codec, w, h, says) -> None:
    monkeypatch.setattr(formats, "ffmpeg_encoders", lambda: frozenset({"hap"}))
    plan = plan_output(tmp_path / "x.mov", False, codec)
    with pytest.raises(FormatError, match=says):
        plan.check_size(w, h)


def test_render_refuses_before_opening_the_input(tmp_path) -> None:
    """A bad pairing is found before the input is read: a missing input is not reached."""
    with pytest.raises(FormatError, match="cannot hold 'libx264'"):
        render_file(fake(), tmp_path / "missing.mp4", tmp_path / "o.webm",
                    constant_angle(90, 0.5, 0.0), backend="cpu", codec="libx264",
                    progress=False)  # fmt: skip
    with pytest.raises(FormatError, match="needs at least 256x120"):
        render_file(fake(), tmp_path / "missing.mp4", tmp_path / "o.mov",
                    constant_angle(90, 0.5, 0.0), backend="cpu", codec="dnxhd",
                    progress=False)  # fmt: skip
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def _cli(args: list[str], cwd: Path, monkeypatch, capsys) -> tuple[int, str]:
    """(exit status, stderr) of ``viewcomp ARGS`` run in ``cwd``, in this process."""
    from viewcomp.cli import main

    monkeypatch.chdir(cwd)
    try:
        code = main(args)
    except SystemExit as exc:  # argparse's and UsageError's way out
        code = int(exc.code or 0)
    return code, capsys.readouterr().err


@pytest.mark.parametrize(
    ("out", "extra", "says"),
    [
        ("x.webm", ["--codec", "libx264"], "a .webm file cannot hold 'libx264'"),
        ("x.mp4", ["--codec", "prores_ks"], "prores_ks goes in .mov"),
        ("x.mp4", ["--codec", "ffv1"], "ffv1 goes in .mkv"),
        ("x.xyz", [], "unknown video extension '.xyz'"),
    ],
)
def test_cli_exits_2_with_the_pairings_before_loading_anything(
    tmp_path, monkeypatch, capsys, out, extra, says
) -> None:
    """The calibration is not even a calibration: the output check comes first."""
    (tmp_path / "cal.vcb").write_bytes(b"not a calibration")
    make_test_video(str(tmp_path / "in.mp4"), 32, 16, seconds=0.2, rate=10, audio=False)
    args = ["render", "cal.vcb", "in.mp4", "-o", out, "--angle", "60", *extra]
    code, err = _cli(args, tmp_path, monkeypatch, capsys)
    assert code == 2, err
    assert says in err and PAIRINGS in err
    assert "Traceback" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cal.vcb", "in.mp4"]


def test_truncated_mp4_is_called_incomplete(tmp_path) -> None:
    src = tmp_path / "in.mp4"
    make_test_video(str(src), 32, 16, seconds=1.0, rate=10, audio=True)
    data = src.read_bytes()
    cut = tmp_path / "cut.mp4"
    cut.write_bytes(data[: len(data) // 3])  # moov is at the end: cut off
    assert mp4_missing_index(cut) and not mp4_missing_index(src)
    with pytest.raises(av.FFmpegError) as info:
        av.open(str(cut))
    cause, fix = describe_av_error(info.value, cut)
    assert cause == "the file is incomplete (no index)"
    assert fix.startswith("was it still being written?")
    junk = tmp_path / "junk.mp4"
    junk.write_bytes(b"\x00\x00\x00\x18ftypmp42" + bytes(range(256)) * 8)
    with pytest.raises(av.FFmpegError) as info:
        av.open(str(junk))
    cause, fix = describe_av_error(info.value, junk)
    assert "Errno" not in cause and "1094995529" not in cause and "damaged" in cause
    assert "ffmpeg -i" in fix


def test_cli_truncated_input_message(tmp_path) -> None:
    from viewcomp.rt.media.video import VideoError, VideoReader

    src = tmp_path / "in.mp4"
    make_test_video(str(src), 32, 16, seconds=1.0, rate=10)
    cut = tmp_path / "cut.mp4"
    cut.write_bytes(src.read_bytes()[:2000])
    with pytest.raises(VideoError) as info:
        VideoReader(cut)
    msg = str(info.value)
    assert msg == (
        f"cannot read video {cut}: the file is incomplete (no index); fix: was it still "
        "being written? re-encode it or copy it again"
    )
    assert "moov" not in msg and "Errno" not in msg


def test_encoder_errors_are_not_blamed_on_the_folder(tmp_path, monkeypatch) -> None:
    """FFmpeg's EPERM from an encoder (what h264_nvenc says without a GPU) is the encoder's;
    a full disk is the disk's. Neither shows FFmpeg's codes."""
    import errno

    from viewcomp.rt.media.video import VideoError, VideoWriter

    for exc, says, not_says in [
        (av.error.PermissionError(errno.EPERM, "Operation not permitted", "avcodec_open2"),
         "FFmpeg failed while encoding (Operation not permitted)", "permissions"),
        (av.error.InvalidDataError(-1094995529, "Invalid data found when processing input"),
         "FFmpeg failed while encoding", "1094995529"),
        (OSError(errno.ENOSPC, "No space left on device"), "free some space", "FFmpeg"),
    ]:  # fmt: skip
        writer = VideoWriter(tmp_path / "o.mp4", 64, 32, Fraction(10))

        def fail(rgb, exc=exc):
            raise exc

        monkeypatch.setattr(writer, "_write", fail)
        with pytest.raises(VideoError) as info:
            writer.write(np.zeros((32, 64, 3), np.uint8))
        writer.abort()
        msg = str(info.value)
        assert msg.startswith(f"cannot write video {tmp_path / 'o.mp4'}") and says in msg
        assert not_says not in msg and "Errno" not in msg
    assert list(tmp_path.iterdir()) == []
