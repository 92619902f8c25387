"""Video in and out with PyAV: a threaded decoder yielding yuv420p planes, and an encoder.

No GL here: :class:`VideoReader` decodes on a worker thread into a bounded queue and yields
:class:`~viewcomp.rt.media.frames.Planes` (already fitted to the projector grid) and audio items;
:class:`VideoWriter` encodes RGB frames (H.264 via libx264 by default, the input's frame
rate; codec, pixel format, profile and audio codec as :mod:`viewcomp.rt.media.formats`
plans them) and carries the audio over, writing to a temporary file in the output's folder
that replaces the output only when everything succeeded.

Decisions:

- Frames of another size are scaled on the worker thread with swscale (bilinear) to fit the
  grid, aspect kept, at even offsets, centred on black (Y = 16 or 0, C = 128). Both backends
  then see the very same planes, hence the same RGB (:mod:`viewcomp.rt.media.frames`).
- Colour metadata: BT.709 if the stream says so, BT.601 for BT.470BG/SMPTE170M; when
  unspecified, BT.709 for height >= 720 and BT.601 below (FFmpeg's and players' habit).
  ``yuvj*`` formats and ``color_range = JPEG`` are full range, anything else limited.
  Formats other than yuv420p/yuvj420p (10-bit, 4:2:2, ...) are converted to 8-bit yuv420p
  by swscale keeping matrix and range.
- Output timestamps are frame index / rate (constant frame rate = the input's average rate);
  the frame count is kept. The output is tagged limited range with the input's matrix.
- Encoding: H.264 (libx264) CRF 18, preset ``veryfast`` by default (x264's own default,
  ``medium``, costs ~3x the CPU time for somewhat smaller files); the preset applies to
  libx264/libx265 only. :class:`EncodeThread` runs the encoder on its own thread behind a
  bounded queue, so encoding overlaps decoding and the GL work (PyAV releases the GIL while
  it converts and encodes).
- Pixel formats: yuv420p for H.264/H.265/VP9/AV1, yuv422p10le for ProRes, yuv444p for FFV1
  (the table in :mod:`viewcomp.rt.media.formats`); swscale converts the RGB frames with the
  input's matrix, limited range.
- Audio: remuxed (packets copied) when the output container takes the codec, else decoded on
  the worker thread and re-encoded (AAC for .mp4/.mov, Opus at 48 kHz for .mkv/.webm).
  Audio timestamps are shifted by the video stream's start time so that A/V sync is kept
  with video starting at 0.
"""

from __future__ import annotations

import errno
import logging
import os
import queue
import threading
from collections.abc import Iterator
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import Any, Literal

import av
import numpy as np

from viewcomp.calib.errors import VideoError, describe_os_error
from viewcomp.calib.io.atomic import AtomicFile
from viewcomp.rt.media.averrors import DAMAGED_FIX, describe_av_error
from viewcomp.rt.media.formats import OutputPlan, plan_output
from viewcomp.rt.media.frames import ColorRange, Colorspace, Planes, fit_rect, pad_planes

log = logging.getLogger(__name__)

AudioMode = Literal["packets", "frames", "none"]

VIDEO_FIX = DAMAGED_FIX
X264_PRESETS = (
    "ultrafast", "superfast", "veryfast", "faster", "fast", "medium", "slow", "slower",
    "veryslow", "placebo",
)  # fmt: skip
DEFAULT_PRESET = "veryfast"
# FFmpeg errors that are the disk's, not the encoder's (a full disk, a read-only or vanished
# file system): reported with the output's path and what to do about the disk.
_DISK_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EIO, errno.ENOENT, errno.EFBIG}
_OPUS_RATES = (48000, 24000, 16000, 12000, 8000)  # the only rates Opus encodes
_STD_LAYOUTS = {1: "mono", 2: "stereo", 3: "2.1", 4: "quad", 5: "5.0", 6: "5.1", 8: "7.1"}
_QUEUE_POLL = 0.1  # seconds between checks of the stop flag while the queue is full


@dataclass(frozen=True)
class VideoInfo:
    """What the pipeline needs to know about an input video before decoding it.

    ``rate`` frames per second; ``frames`` the container's count or duration x rate (an
    estimate, or None); ``duration`` seconds or None; ``start`` the video stream's first
    timestamp in seconds.
    """

    path: Path
    width: int
    height: int
    rate: Fraction
    frames: int | None
    duration: float | None
    start: float
    colorspace: Colorspace
    color_range: ColorRange
    audio_codec: str | None


@dataclass
class AudioItem:
    """An audio packet to remux (``packet``) or a decoded audio frame to encode (``frame``)."""

    packet: Any = None
    frame: Any = None


@dataclass
class _Failure:
    exc: BaseException


_END = object()


def _colorspace(code: int, height: int) -> Colorspace:
    if code == 1:
        return "bt709"
    if code in (5, 6):
        return "bt601"
    return "bt709" if height >= 720 else "bt601"


class VideoReader:
    """Decode a video on a worker thread into fitted yuv420p planes.

    Args:
        path: the input video.
        fit: (W, H) of the projector grid; frames are scaled to fit (aspect kept, centred on
            black). None keeps the input size.
        audio: ``"packets"`` to yield audio packets for remuxing, ``"frames"`` to yield
            decoded audio frames for re-encoding, ``"none"`` to skip audio.
        queue_size: bound of the frame queue (decoded frames held in memory at most).
        start_at: seconds from the first frame to start at (a seek: the container seeks to
            the keyframe before it and the frames and audio before it are skipped).

    Iterating yields :class:`Planes` (with ``time`` in seconds from the first frame) and
    :class:`AudioItem`, in demux order. Decoding errors surface as :class:`VideoError` in the
    consuming thread. Use as a context manager, or call :meth:`close`.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        fit: tuple[int, int] | None = None,
        audio: AudioMode = "packets",
        queue_size: int = 8,
        start_at: float = 0.0,
    ) -> None:
        self.path = Path(path)
        self.fit = fit
        self.start_at = max(float(start_at), 0.0)
        self.audio_mode: AudioMode = audio
        self._queue: queue.Queue[Any] = queue.Queue(maxsize=queue_size)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        try:
            self.container = av.open(str(self.path), "r")
        except (av.FFmpegError, OSError, ValueError) as exc:
            cause, fix = describe_av_error(exc, self.path)
            raise VideoError(f"cannot read video {self.path}: {cause}; fix: {fix}") from exc
        try:
            self.info = self._probe()
        except BaseException:  # undo on any failure, Ctrl-C included; then re-raise
            self.container.close()
            raise

    def _probe(self) -> VideoInfo:
        if not self.container.streams.video:
            raise VideoError(
                f"cannot read video {self.path}: it has no video stream; fix: {VIDEO_FIX}"
            )
        vs = self.container.streams.video[0]
        self.video_stream = vs
        self.audio_stream = (
            self.container.streams.audio[0] if self.container.streams.audio else None
        )
        cc = vs.codec_context
        rate = vs.average_rate or vs.guessed_rate or vs.base_rate
        if not rate or rate <= 0 or not cc.width or not cc.height:
            raise VideoError(
                f"cannot read video {self.path}: no frame rate or size in its video stream; "
                f"fix: {VIDEO_FIX}"
            )
        rate = Fraction(rate)
        duration = None
        if vs.duration is not None and vs.time_base is not None:
            duration = float(vs.duration * vs.time_base)
        elif self.container.duration is not None:
            duration = self.container.duration / av.time_base
        frames = int(vs.frames) if vs.frames else None
        if frames is None and duration is not None:
            frames = round(duration * rate)
        start = float(vs.start_time * vs.time_base) if vs.start_time is not None else 0.0
        fmt = cc.format.name if cc.format is not None else ""
        full = fmt.startswith("yuvj") or int(cc.color_range or 0) == 2
        return VideoInfo(
            path=self.path,
            width=int(cc.width),
            height=int(cc.height),
            rate=rate,
            frames=frames,
            duration=duration,
            start=start,
            colorspace=_colorspace(int(cc.colorspace or 2), int(cc.height)),
            color_range="full" if full else "limited",
            audio_codec=self.audio_stream.codec_context.name if self.audio_stream else None,
        )

    # ------------------------------------------------------------------ worker
    def _put(self, item: Any) -> bool:
        while not self._stop.is_set():
            try:
                self._queue.put(item, timeout=_QUEUE_POLL)
                return True
            except queue.Full:
                continue
        return False

    def _planes(self, frame: av.VideoFrame, t0: float) -> Planes:
        fmt = frame.format.name
        full = fmt.startswith("yuvj") or int(frame.color_range or 0) == 2
        crange: ColorRange = "full" if full else "limited"
        cspace = _colorspace(int(frame.colorspace or 2), frame.height)
        w, h = frame.width, frame.height
        tw, th = self.fit if self.fit is not None else (w, h)
        x0, y0, fw, fh = fit_rect(w, h, tw, th, even=True)
        if (fw, fh) != (w, h) or fmt not in ("yuv420p", "yuvj420p"):
            rng = (
                av.video.reformatter.ColorRange.JPEG
                if full
                else av.video.reformatter.ColorRange.MPEG
            )
            frame = frame.reformat(
                width=fw, height=fh, format="yuv420p", src_color_range=rng, dst_color_range=rng
            )
        planes = []
        for p in frame.planes:
            arr = np.frombuffer(p, np.uint8).reshape(p.height, p.line_size)[:, : p.width]
            planes.append(arr)
        if (fw, fh) == (tw, th):
            y, u, v = (np.ascontiguousarray(a) for a in planes)
        else:
            y, u, v = pad_planes(planes[0], planes[1], planes[2], x0, y0, tw, th, crange)
        t = float(frame.time) - t0 if frame.time is not None else 0.0
        return Planes(y, u, v, cspace, crange, t)

    def _run(self) -> None:
        try:
            streams = [self.video_stream]
            if self.audio_stream is not None and self.audio_mode != "none":
                streams.append(self.audio_stream)
            t0 = self.info.start
            skip = self.start_at - 0.5 / float(self.info.rate)  # frames before it are skipped
            if self.start_at > 0.0:
                vs = self.video_stream
                self.container.seek(
                    int((t0 + self.start_at) / vs.time_base),
                    stream=vs,
                    backward=True,
                    any_frame=False,
                )
            for packet in self.container.demux(streams):
                if self._stop.is_set():
                    return
                if packet.stream.type == "video":
                    for frame in packet.decode():
                        t = float(frame.time) - t0 if frame.time is not None else 0.0
                        if self.start_at > 0.0 and t < skip:
                            continue
                        if not self._put(self._planes(frame, t0)):
                            return
                elif self.audio_mode == "packets":
                    if packet.size and packet.dts is not None:
                        if not self._put(AudioItem(packet=packet)):
                            return
                else:
                    for aframe in packet.decode():
                        t = float(aframe.time) - t0 if aframe.time is not None else 0.0
                        if self.start_at > 0.0 and t < self.start_at:
                            continue
                        if not self._put(AudioItem(frame=aframe)):
                            return
            self._put(_END)
        except BaseException as exc:  # handed to the consumer, which re-raises it
            self._put(_Failure(exc))

    # ------------------------------------------------------------------ consumer
    def __iter__(self) -> Iterator[Planes | AudioItem]:
        if self._thread is not None:
            raise RuntimeError("a VideoReader can be iterated once")
        self._thread = threading.Thread(target=self._run, name="viewcomp-decode", daemon=True)
        self._thread.start()
        while True:
            item = self._queue.get()
            if item is _END:
                return
            if isinstance(item, _Failure):
                cause, fix = describe_av_error(item.exc, self.path)
                raise VideoError(
                    f"cannot decode video {self.path}: {cause}; fix: {fix}"
                ) from item.exc
            yield item

    def close(self) -> None:
        """Stop the worker thread and close the file."""
        self._stop.set()
        if self._thread is not None:
            while self._thread.is_alive():
                try:  # unblock a worker waiting on a full queue
                    self._queue.get_nowait()
                except queue.Empty:
                    pass
                self._thread.join(timeout=_QUEUE_POLL)
        self.container.close()

    def __enter__(self) -> VideoReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class VideoWriter:
    """Encode RGB frames to a video, carrying one audio stream over; atomic on success.

    Args:
        path: the output file; its extension picks the container (``.mp4``, ``.mkv``, ...).
        width, height: frame size in pixels (yuv420p codecs want even sizes).
        rate: frames per second (the input's).
        codec: FFmpeg encoder name (or an alias, ``prores``); None: the container's default
            (libx264 for .mp4/.mkv/.mov, libvpx-vp9 for .webm).
        crf: constant rate factor for the encoders that have one (x264/x265/vp9/svt-av1).
        colorspace: matrix to encode and tag with (``bt601``/``bt709``); range is limited.
        audio: the input's audio stream (a template; read before decoding starts) or None.
        preset: x264/x265 speed preset (:data:`X264_PRESETS`), ``veryfast`` by default;
            ignored by other encoders.
        profile: the codec's profile (ProRes ``hq``, ...; :mod:`viewcomp.rt.media.formats`).
        plan: an already checked :class:`OutputPlan` (then ``codec``/``profile`` are unused).

    Frames are written with :meth:`write`, audio with :meth:`write_audio`; :meth:`close`
    flushes and renames into place, :meth:`abort` (or an exception in a ``with`` block)
    deletes the temporary file. :attr:`audio_mode` tells the reader what to deliver.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        width: int,
        height: int,
        rate: Fraction,
        codec: str | None = None,
        crf: float = 18,
        colorspace: Colorspace = "bt709",
        audio: Any = None,
        audio_start: float = 0.0,
        preset: str = DEFAULT_PRESET,
        profile: str | None = None,
        plan: OutputPlan | None = None,
    ) -> None:
        if plan is None:
            plan = plan_output(path, False, codec, profile)
        if plan.kind != "video" or plan.codec is None or plan.codec.via_ffmpeg:
            raise ValueError(f"VideoWriter writes PyAV video files, not {plan.kind} {path}")
        self.plan = plan
        if plan.codec.preset and preset not in X264_PRESETS:
            raise VideoError(
                f"cannot write video {path}: unknown preset {preset!r}; fix: use one of "
                f"{', '.join(X264_PRESETS)}"
            )
        self.preset = preset
        self.path = Path(path)
        self.colorspace = colorspace
        self._index = 0
        self._closed = False
        try:
            self._target = AtomicFile(self.path)
        except OSError as exc:
            raise VideoError(f"cannot write video {describe_os_error(exc, self.path)}") from exc
        self.tmp = self._target.tmp
        try:
            self.container = av.open(str(self.tmp), "w")
        except (av.FFmpegError, OSError, ValueError) as exc:
            self._target.discard(exc)
            cause, _ = describe_av_error(exc)
            raise VideoError(
                f"cannot write video {self.path}: {cause}; fix: use a writable folder"
            ) from exc
        try:
            self._setup(width, height, rate, crf, audio, audio_start)
        except BaseException:  # undo on any failure, Ctrl-C included; then re-raise
            self.abort()
            raise

    def _setup(
        self,
        width: int,
        height: int,
        rate: Fraction,
        crf: float,
        audio: Any,
        audio_start: float,
    ) -> None:
        plan = self.plan
        assert plan.codec is not None
        codec = plan.codec.encoder
        plan.codec.quiet()
        try:
            vs = self.container.add_stream(codec, rate=rate)
        except (av.FFmpegError, ValueError) as exc:  # the plan checked it exists: rare
            cause, _ = describe_av_error(exc)
            raise VideoError(
                f"cannot write video {self.path}: the encoder {codec!r} cannot start ({cause}); "
                "fix: use --codec libx264"
            ) from exc
        vs.width, vs.height = width, height
        vs.pix_fmt = plan.pix_fmt
        cc = vs.codec_context
        cc.time_base = Fraction(1) / rate
        cc.framerate = rate
        cc.colorspace = 1 if self.colorspace == "bt709" else 6
        cc.color_range = 1
        vs.options = plan.encoder_options(crf, self.preset)
        self.video = vs
        self.audio_mode: AudioMode = "none"
        self.audio_out: Any = None
        self._audio_shift = audio_start
        if audio is None:
            return
        name = audio.codec_context.name
        how = plan.audio_plan(name)
        if how is not None and how[0] == "copy" and name in self.container.supported_codecs:
            self.audio_out = self.container.add_stream_from_template(audio)
            self.audio_mode = "packets"
        else:
            acc = audio.codec_context
            encoder = plan.container.audio_encoder if plan.container else "aac"
            sr = acc.sample_rate or 48000
            if encoder == "libopus" and sr not in _OPUS_RATES:
                sr = 48000  # PyAV's encoder resamples the frames to the stream's rate
            self.audio_out = self.container.add_stream(encoder, rate=sr)
            n = acc.layout.nb_channels if acc.layout is not None else 2
            # Streams without a channel order ("2 channels") get the standard one.
            self.audio_out.layout = _STD_LAYOUTS.get(n, "stereo")
            self.audio_mode = "frames"

    def write(self, rgb: np.ndarray) -> None:
        """Encode one RGB frame (H, W, 3) uint8 at timestamp index / rate."""
        try:
            self._write(rgb)
        except (OSError, av.FFmpegError) as exc:
            raise self._write_error(exc) from exc

    def _write_error(self, exc: BaseException) -> VideoError:
        """A failure while encoding, in plain words: the disk's (full, read-only, gone: named
        by the output's path) or the encoder's (FFmpeg's words without its code; FFmpeg's
        EPERM/EACCES from an encoder are not about the folder)."""
        disk = isinstance(exc, OSError) and (
            not isinstance(exc, av.FFmpegError) or exc.errno in _DISK_ERRNOS
        )
        if disk:
            assert isinstance(exc, OSError)
            return VideoError(f"cannot write video {describe_os_error(exc, self.path)}")
        cause, _ = describe_av_error(exc)
        return VideoError(
            f"cannot write video {self.path}: FFmpeg failed while encoding ({cause}); fix: "
            "try another codec, or the default one (leave out --codec and --profile)"
        )

    def _write(self, rgb: np.ndarray) -> None:
        frame = av.VideoFrame.from_ndarray(rgb, format="rgb24")
        cs = av.video.reformatter.Colorspace
        frame = frame.reformat(
            format=self.video.pix_fmt,
            dst_colorspace=cs.ITU709 if self.colorspace == "bt709" else cs.ITU601,
            dst_color_range=av.video.reformatter.ColorRange.MPEG,
        )
        frame.pts = self._index
        frame.time_base = self.video.codec_context.time_base
        self._index += 1
        for packet in self.video.encode(frame):
            self.container.mux(packet)

    def write_audio(self, item: AudioItem) -> None:
        """Remux an audio packet or encode an audio frame (as :attr:`audio_mode` says)."""
        try:
            self._write_audio(item)
        except (OSError, av.FFmpegError) as exc:
            raise self._write_error(exc) from exc

    def _write_audio(self, item: AudioItem) -> None:
        if self.audio_out is None:
            return
        if item.packet is not None:
            pkt = item.packet
            shift = round(self._audio_shift / pkt.time_base) if pkt.time_base else 0
            if pkt.pts is not None:
                pkt.pts -= shift
            if pkt.dts is not None:
                pkt.dts -= shift
            pkt.stream = self.audio_out
            self.container.mux(pkt)
        elif item.frame is not None:
            fr = item.frame
            if fr.pts is not None and fr.time_base:
                fr.pts -= round(self._audio_shift / fr.time_base)
            for packet in self.audio_out.encode(fr):
                self.container.mux(packet)

    @property
    def frames_written(self) -> int:
        """Video frames encoded so far."""
        return self._index

    def close(self) -> None:
        """Flush the encoders, close the file and move it to :attr:`path`."""
        if self._closed:
            return
        try:
            for packet in self.video.encode(None):
                self.container.mux(packet)
            if self.audio_mode == "frames":
                for packet in self.audio_out.encode(None):
                    self.container.mux(packet)
            self.container.close()
        except (OSError, av.FFmpegError) as exc:  # undo, then name the output (not the
            self._abort(exc)  # temporary file) or the encoder
            raise self._write_error(exc) from exc
        except BaseException as exc:  # undo on any failure, Ctrl-C included; then re-raise
            self._abort(exc)
            raise
        self._closed = True
        self._target.commit()

    def abort(self) -> None:
        """Close without finishing and delete the temporary file; no output is left."""
        self._abort(None)

    def _abort(self, cause: BaseException | None) -> None:
        if self._closed:
            return
        self._closed = True
        try:
            self.container.close()
        except av.FFmpegError as exc:  # the file is deleted next; its state does not matter,
            # and the error that made us abort is the one to report
            log.debug("closing the partial video %s failed: %s", self.tmp, exc)
        finally:
            self._target.discard(cause)

    def __enter__(self) -> VideoWriter:
        return self

    def __exit__(self, exc_type: object, *exc: object) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()
