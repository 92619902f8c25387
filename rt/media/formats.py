"""The output formats of ``viewcomp render``: which codec goes in which container, how.

One table (:data:`CONTAINERS`, :data:`CODECS`) says, for each output extension, the video
codecs it can hold (the first is the default), the pixel format, bit depth and profiles of
each codec, which audio codecs are copied as they are and which encoder re-encodes the rest.
:func:`plan_output` checks an output path, a codec and a profile against it *before any work*
(before the input is opened) and returns an :class:`OutputPlan`; :meth:`OutputPlan.check_size`
then checks the projector grid's size and opens the encoder once on a tiny frame, so an
encoder that is in FFmpeg's list but cannot start (``h264_nvenc`` without an NVIDIA driver)
is refused before decoding starts, as such.

Decisions:

- Containers: ``.mp4`` (H.264, H.265, AV1), ``.mov`` (H.264, H.265, ProRes, DNxHR, HAP),
  ``.mkv`` (H.264, H.265, VP9, AV1, FFV1), ``.webm`` (VP9, AV1). ``.mp4``, ``.mov`` and
  ``.mkv`` default to H.264 (what every player takes), ``.webm`` to VP9.
- Pixel formats: 8-bit 4:2:0 for the delivery codecs (H.264/H.265/VP9/AV1: what hardware
  decoders take), 10-bit 4:2:2 for ProRes (``hq`` by default: 422 HQ, the usual master for
  media servers), 8-bit 4:2:2 for DNxHR HQ (``hqx``: 10-bit), 4:4:4 for FFV1 (lossless: no
  chroma subsampling of the compensated picture). HAP is DXT-compressed RGB (``hap``, or
  ``hap_q``, higher quality and twice the size).
- Audio: copied when the container takes the input's codec, else re-encoded: AAC for
  ``.mp4``/``.mov``, Opus for ``.mkv``/``.webm`` (WebM takes only Opus and Vorbis).
- HAP is not in PyAV's FFmpeg build: it goes through the system's ``ffmpeg`` program when
  that has the ``hap`` encoder (raw RGB frames piped in; the audio read from the input by
  ffmpeg itself), else it is refused, saying so.
- Image sequences: ``-o DIR/%05d.png`` (a printf pattern, FFmpeg's convention; ``.png``,
  ``.jpg``, ``.tif``), numbered from 0 (frame N shows time N / rate). The folder is new or
  empty and appears whole at the end; no audio. A bare folder is refused (which image
  format?) with the pattern to give instead.
- Stills (an image input): ``.png``, ``.jpg``/``.jpeg``, ``.tif``/``.tiff``, 8-bit RGB. The
  compensation's output is 8-bit, so a 16-bit TIFF would only pad it: not offered.
"""

from __future__ import annotations

import functools
import os
import re
import shutil
import subprocess
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path
from typing import Literal, cast

import av

from viewcomp.calib.errors import ViewcompError

OutputKind = Literal["video", "sequence", "still"]

STILL_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff")
# A printf frame number in a file name: %d or %0Nd (N <= 9), as FFmpeg's image2 muxer reads.
_FRAME_NUMBER = re.compile(r"%0?[1-9]?d")
# The smallest frame the encoder is tried on before any work (width, height): a multiple of
# 4 (DXT, chroma subsampling), raised to the codec's minimum.
_PROBE_SIZE = (64, 32)


class FormatError(ViewcompError, ValueError):
    """An output whose extension, codec, profile or size cannot work together; the message
    lists what does."""


@dataclass(frozen=True)
class VideoCodec:
    """One video encoder and what it needs.

    ``encoder``: FFmpeg's encoder name; ``label``: what people call it; ``profiles``: profile
    name -> (the encoder's ``profile`` option value or None, pixel format, bits per sample),
    the first being the default; ``crf``/``preset``: whether ``--crf``/``--preset`` apply;
    ``multiple``: width and height must be multiples of it; ``min_size``: (width, height) at
    least; ``via_ffmpeg``: encoded by the system's ``ffmpeg`` program, not PyAV.
    """

    encoder: str
    label: str
    profiles: dict[str, tuple[str | None, str, int]]
    crf: bool = False
    preset: bool = False
    multiple: int = 2
    min_size: tuple[int, int] = (2, 2)
    via_ffmpeg: bool = False
    options: dict[str, str] = field(default_factory=dict)
    env: dict[str, str] = field(default_factory=dict)

    def quiet(self) -> None:
        """Set the environment variables (unless set already) that keep the encoder library
        from logging its set-up to stderr on every file (SVT-AV1 reads ``SVT_LOG``)."""
        for key, value in self.env.items():
            os.environ.setdefault(key, value)

    @property
    def default_profile(self) -> str:
        """The profile used when none is asked for."""
        return next(iter(self.profiles))


_YUV420: dict[str, tuple[str | None, str, int]] = {"main": (None, "yuv420p", 8)}
_YUV444: dict[str, tuple[str | None, str, int]] = {"main": (None, "yuv444p", 8)}
CODECS: dict[str, VideoCodec] = {
    c.encoder: c
    for c in (
        VideoCodec("libx264", "H.264", _YUV420, crf=True, preset=True),
        VideoCodec(
            "libx265",
            "H.265/HEVC",
            _YUV420,
            crf=True,
            preset=True,
            options={"x265-params": "log-level=error"},  # x265 logs every encode to stderr
        ),
        VideoCodec("h264_nvenc", "H.264 (NVIDIA)", _YUV420),
        VideoCodec("hevc_nvenc", "H.265 (NVIDIA)", _YUV420),
        # VP9 in constant-quality mode needs the bit rate at 0 besides the CRF.
        VideoCodec("libvpx-vp9", "VP9", _YUV420, crf=True, options={"b": "0", "row-mt": "1"}),
        VideoCodec("libsvtav1", "AV1", _YUV420, crf=True, env={"SVT_LOG": "1"}),  # errors only
        VideoCodec("ffv1", "FFV1 (lossless)", _YUV444),
        VideoCodec(
            "prores_ks",
            "Apple ProRes",
            {
                "hq": ("3", "yuv422p10le", 10),
                "standard": ("2", "yuv422p10le", 10),
                "lt": ("1", "yuv422p10le", 10),
                "proxy": ("0", "yuv422p10le", 10),
                "4444": ("4", "yuv444p10le", 10),
            },
        ),
        VideoCodec(
            "dnxhd",
            "Avid DNxHR",
            {
                "hq": ("dnxhr_hq", "yuv422p", 8),
                "sq": ("dnxhr_sq", "yuv422p", 8),
                "lb": ("dnxhr_lb", "yuv422p", 8),
                "hqx": ("dnxhr_hqx", "yuv422p10le", 10),
            },
            min_size=(256, 120),  # the encoder's own limit
        ),
        VideoCodec(
            "hap",
            "HAP (Vidvox)",
            {"hap": ("hap", "rgb24", 8), "hap_q": ("hap_q", "rgb24", 8)},
            multiple=4,  # DXT blocks are 4x4 pixels
            via_ffmpeg=True,
        ),
    )
}

# Names people use for the codecs -> the encoder.
ALIASES = {
    "h264": "libx264",
    "x264": "libx264",
    "h265": "libx265",
    "hevc": "libx265",
    "x265": "libx265",
    "vp9": "libvpx-vp9",
    "av1": "libsvtav1",
    "prores": "prores_ks",
    "dnxhr": "dnxhd",
}

_PCM = {"pcm_s16le", "pcm_s24le", "pcm_s32le", "pcm_f32le", "pcm_s16be", "pcm_s24be"}


@dataclass(frozen=True)
class Container:
    """An output extension: its FFmpeg muxer, its video codecs (the first is the default),
    the audio codecs it takes as they are, and the encoder for any other audio."""

    extensions: tuple[str, ...]
    muxer: str
    codecs: tuple[str, ...]
    audio_copy: frozenset[str]
    audio_encoder: str

    @property
    def audio_label(self) -> str:
        """The re-encoded audio's name, for messages and the documentation."""
        return "Opus" if self.audio_encoder == "libopus" else "AAC"


_NVENC = ("h264_nvenc", "hevc_nvenc")
CONTAINERS: tuple[Container, ...] = (
    Container(
        (".mp4", ".m4v"),
        "mp4",
        ("libx264", "libx265", "libsvtav1", *_NVENC),
        frozenset({"aac", "mp3", "alac", "opus", "flac", "ac3", "eac3"}),
        "aac",
    ),
    Container(
        (".mov",),
        "mov",
        ("libx264", "libx265", "prores_ks", "dnxhd", "hap", *_NVENC),
        frozenset({"aac", "alac", "mp3", *_PCM}),
        "aac",
    ),
    Container(
        (".mkv",),
        "matroska",
        ("libx264", "libx265", "libvpx-vp9", "libsvtav1", "ffv1", *_NVENC),
        frozenset({"aac", "mp3", "opus", "vorbis", "flac", "ac3", "eac3", "alac", *_PCM}),
        "libopus",
    ),
    Container(
        (".webm",), "webm", ("libvpx-vp9", "libsvtav1"), frozenset({"opus", "vorbis"}), "libopus"
    ),
)


def is_sequence_pattern(path: str | Path) -> bool:
    """True when the output's file name holds a printf frame number (``%05d``): one image
    per frame."""
    return bool(_FRAME_NUMBER.search(Path(path).name))


def container_for(suffix: str) -> Container | None:
    """The container of an extension (``.mp4``, case ignored), or None."""
    s = suffix.lower()
    return next((c for c in CONTAINERS if s in c.extensions), None)


def pairings() -> str:
    """The working extension/codec pairings, one clause per container, for messages."""
    parts = []
    for c in CONTAINERS:
        names = ", ".join(c.codecs)
        parts.append(f"{'/'.join(c.extensions)}: {names} (default {c.codecs[0]})")
    parts.append("image sequence: DIR/%05d.png (or .jpg, .tif)")
    return "; ".join(parts)


@dataclass(frozen=True)
class OutputPlan:
    """What to write and how; checked against the table, not yet against the grid's size.

    ``kind``: ``video`` (one file), ``sequence`` (numbered images in a folder) or ``still``
    (one image). For video: ``container`` and ``codec``, ``profile`` (a key of the codec's
    profiles), ``pix_fmt`` and ``depth`` (bits per sample) it encodes with.
    """

    path: Path
    kind: OutputKind
    container: Container | None = None
    codec: VideoCodec | None = None
    profile: str | None = None

    @property
    def pix_fmt(self) -> str:
        """The pixel format the encoder gets (``yuv420p``, ``yuv422p10le``, ...)."""
        assert self.codec is not None and self.profile is not None
        return self.codec.profiles[self.profile][1]

    @property
    def depth(self) -> int:
        """Bits per sample of :attr:`pix_fmt`."""
        assert self.codec is not None and self.profile is not None
        return self.codec.profiles[self.profile][2]

    def encoder_options(self, crf: float, preset: str) -> dict[str, str]:
        """The encoder's options: the codec's own, its profile, ``crf`` and ``preset`` where
        the codec has them."""
        assert self.codec is not None and self.profile is not None
        opts = dict(self.codec.options)
        value = self.codec.profiles[self.profile][0]
        if value is not None and not self.codec.via_ffmpeg:
            opts["profile"] = value
        if self.codec.crf:
            opts["crf"] = f"{crf:g}"
        if self.codec.preset:
            opts["preset"] = preset
        return opts

    def audio_plan(self, input_codec: str | None) -> tuple[str, str] | None:
        """``("copy", codec)`` when the container takes the input's audio as it is,
        ``("encode", encoder)`` when it must be re-encoded, None without audio (or for
        image outputs, which have none)."""
        if input_codec is None or self.container is None:
            return None
        if input_codec in self.container.audio_copy:
            return ("copy", input_codec)
        return ("encode", self.container.audio_encoder)

    def check_size(self, width: int, height: int) -> None:
        """Refuse a grid the encoder cannot take, and try the encoder (PyAV's) on one tiny
        frame so that one present in FFmpeg's list but unable to start (a hardware encoder
        without its driver) is refused now, before the input is decoded. FormatError."""
        c = self.codec
        if self.kind != "video" or c is None:
            return
        where = f"cannot write {self.path}"
        if width % c.multiple or height % c.multiple:
            raise FormatError(
                f"{where}: {c.label} needs a width and height that are multiples of "
                f"{c.multiple}, the projector grid is {width}x{height} - use another codec "
                f"(e.g. --codec prores_ks in .mov), or calibrate at a size that is"
            )
        if width < c.min_size[0] or height < c.min_size[1]:
            raise FormatError(
                f"{where}: {c.label} needs at least {c.min_size[0]}x{c.min_size[1]} pixels, "
                f"the projector grid is {width}x{height} - use another codec, e.g. "
                "--codec prores_ks in .mov"
            )
        if not c.via_ffmpeg:
            c.quiet()
            size = (max(_PROBE_SIZE[0], c.min_size[0]), max(_PROBE_SIZE[1], c.min_size[1]))
            opts = self.encoder_options(18, "ultrafast")
            _try_encoder(c.encoder, self.pix_fmt, opts, size, self.path)


def plan_output(
    path: str | Path, image_input: bool, codec: str | None = None, profile: str | None = None
) -> OutputPlan:
    """Check an output against the format table before any work (the input is not opened).

    Args:
        path: the output: a still (image input), a video file or an image-sequence pattern
            ``DIR/%05d.png`` (video input).
        image_input: the input is an image (one frame) rather than a video.
        codec: FFmpeg's encoder name or an alias (``h264``, ``prores``, ...); None: the
            container's default.
        profile: one of the codec's profiles (ProRes ``hq``/``standard``/``lt``/``proxy``/
            ``4444``, DNxHR ``hq``/``sq``/``lb``/``hqx``, HAP ``hap``/``hap_q``); None: its
            default.

    Raises:
        FormatError: an unknown extension, a codec the container cannot hold (the message
            lists the pairings that work), a profile the codec lacks, an encoder missing from
            this FFmpeg build, HAP without an ``ffmpeg`` program that has it.
    """
    p = Path(path)
    suffix = p.suffix.lower()
    if image_input:
        if suffix not in STILL_SUFFIXES:
            raise FormatError(
                f"cannot write {p}: an image renders to a .png, .jpg or .tif file (8-bit "
                "RGB) - give e.g. out.png"
            )
        _no_codec_for_images(p, codec, profile, "an image renders to one picture")
        return OutputPlan(p, "still")
    if is_sequence_pattern(p):
        return _plan_sequence(p, codec, profile)
    if suffix in STILL_SUFFIXES:
        raise FormatError(
            f"cannot write {p}: a video renders to a video file or to an image sequence - "
            f"give e.g. out.mp4, out.mov, or {p.parent / 'frames' / ('%05d' + suffix)} for one "
            "image per frame"
        )
    if p.is_dir() or not suffix:
        raise FormatError(
            f"cannot write {p}: give a file name with its extension, or for an image "
            f"sequence a pattern such as {p / '%05d.png'} - the working pairings: {pairings()}"
        )
    cont = container_for(suffix)
    if cont is None:
        raise FormatError(
            f"cannot write {p}: unknown video extension {suffix!r} - the working pairings: "
            f"{pairings()}"
        )
    name = ALIASES.get(codec.lower(), codec) if codec else cont.codecs[0]
    vc = CODECS.get(name)
    if name not in cont.codecs or vc is None:
        holders = [c.extensions[0] for c in CONTAINERS if name in c.codecs]
        hint = f"{name} goes in {', '.join(holders)}; " if holders else ""
        raise FormatError(
            f"cannot write {p}: a {suffix} file cannot hold {name!r} video - {hint}"
            f"the working pairings: {pairings()}"
        )
    if profile is not None and profile not in vc.profiles:
        choices = ", ".join(vc.profiles)
        raise FormatError(
            f"cannot write {p}: {vc.label} has no profile {profile!r} - use one of {choices}"
        )
    prof = profile if profile is not None else vc.default_profile
    if vc.via_ffmpeg:
        _check_ffmpeg_encoder(vc, p)
    elif not _pyav_has_encoder(vc.encoder):
        raise FormatError(
            f"cannot write {p}: the encoder {vc.encoder!r} ({vc.label}) is not in this FFmpeg "
            f"build (PyAV {av.__version__}) - use another codec for {suffix}: "
            f"{', '.join(c for c in cont.codecs if c != vc.encoder)}"
        )
    return OutputPlan(p, "video", cont, vc, prof)


def _plan_sequence(p: Path, codec: str | None, profile: str | None) -> OutputPlan:
    suffix = p.suffix.lower()
    if suffix not in STILL_SUFFIXES:
        raise FormatError(
            f"cannot write {p}: an image sequence is .png, .jpg or .tif images - give e.g. "
            f"{p.parent / '%05d.png'}"
        )
    if len(_FRAME_NUMBER.findall(p.name)) != 1 or "%" in str(p.parent):
        raise FormatError(
            f"cannot write {p}: an image sequence pattern has one frame number in the file "
            f"name, e.g. {p.parent / '%05d.png'}"
        )
    _no_codec_for_images(p, codec, profile, "an image sequence is one image per frame")
    folder = p.parent
    if folder.resolve() == Path.cwd().resolve() or folder.resolve() == folder.resolve().parent:
        raise FormatError(
            f"cannot write {p}: an image sequence gets a folder of its own (it replaces that "
            f"folder whole) - give e.g. {Path('frames') / p.name}"
        )
    if folder.is_file():
        raise FormatError(f"cannot write {p}: {folder} is a file - give a new or empty folder")
    if folder.is_dir() and any(folder.iterdir()):
        raise FormatError(
            f"cannot write {p}: the folder {folder} already holds files, and an image "
            "sequence replaces its folder whole - give a new or empty folder"
        )
    return OutputPlan(p, "sequence")


def _no_codec_for_images(p: Path, codec: str | None, profile: str | None, what: str) -> None:
    if codec is not None or profile is not None:
        raise FormatError(
            f"cannot write {p}: --codec and --profile are for video files ({what}) - "
            "leave them out, or give a video file name"
        )


@functools.cache
def _pyav_has_encoder(name: str) -> bool:
    try:
        av.codec.Codec(name, "w")
    except (av.codec.codec.UnknownCodecError, ValueError):
        return False
    return True


def _try_encoder(
    encoder: str, pix_fmt: str, options: dict[str, str], size: tuple[int, int], path: Path
) -> None:
    """Open ``encoder`` for frames of ``size`` (width, height); FormatError saying why it
    cannot start."""
    try:
        cc = cast(av.VideoCodecContext, av.CodecContext.create(encoder, "w"))
        cc.width, cc.height = size
        cc.pix_fmt = pix_fmt
        cc.options = options
        cc.time_base = Fraction(1, 25)
        cc.framerate = Fraction(25)
        cc.open()
    except (av.FFmpegError, ValueError) as exc:
        hw = "nvenc" in encoder
        cause = (
            "it needs an NVIDIA GPU and its driver, which this machine does not have or cannot open"
            if hw
            else f"FFmpeg cannot start it ({getattr(exc, 'strerror', None) or exc})"
        )
        raise FormatError(
            f"cannot write {path}: the encoder {encoder!r} is in this FFmpeg build but "
            f"{cause} - use a software encoder, e.g. --codec libx264"
        ) from exc


@functools.cache
def ffmpeg_encoders() -> frozenset[str] | None:
    """The encoders of the system's ``ffmpeg`` program (``ffmpeg -encoders``), None when
    there is no such program."""
    exe = shutil.which("ffmpeg")
    if exe is None:
        return None
    try:
        out = subprocess.run(
            [exe, "-hide_banner", "-encoders"],
            capture_output=True,
            text=True,
            timeout=30,
            check=False,
        ).stdout
    except (OSError, subprocess.SubprocessError):
        return None
    names = set()
    for line in out.splitlines():
        parts = line.split()
        if len(parts) >= 2 and len(parts[0]) == 6 and parts[0][0] in "VAS":
            names.add(parts[1])
    return frozenset(names)


def _check_ffmpeg_encoder(vc: VideoCodec, p: Path) -> None:
    encoders = ffmpeg_encoders()
    if encoders is None:
        raise FormatError(
            f"cannot write {p}: {vc.label} is encoded by the ffmpeg program, and there is "
            "none on PATH - install FFmpeg (Debian/Ubuntu: apt install ffmpeg; its build has "
            "the hap encoder), or use --codec prores_ks"
        )
    if vc.encoder not in encoders:
        raise FormatError(
            f"cannot write {p}: the ffmpeg program on PATH ({shutil.which('ffmpeg')}) has no "
            f"{vc.encoder} encoder (`ffmpeg -hide_banner -encoders | grep {vc.encoder}`) - "
            "install an FFmpeg built with it (Debian's has it), or use --codec prores_ks"
        )
