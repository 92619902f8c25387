"""Headless rendering of an image or a video through the compensation (``viewcomp render``).

One function, :func:`render_file`, for both backends and for images and videos::

    decode (worker thread) -> fit to the grid -> thumbnail -> eye = eye_track(t)
        -> p = comp(thumb, eye, t)               (model, alpha, beta for this frame)
        -> compensate (GL Compensator, or viewcomp.calib.model.reference.compensate)
        -> encode (an image, or video on its own thread, audio carried over)

Interfaces:

- ``comp``: the frame parameters, duck-typed like
  :class:`viewcomp.calib.comp.compensation.Compensation`: ``shape`` (H, W), ``method``
  (``"pixel"``/``"paper"``), ``base_model()`` (a model of the right method and grid, used to
  set the GL side up) and ``comp(thumb, eye, t) -> FrameParams`` with ``model``, ``alpha``,
  ``beta``, called once per frame in order (it may smooth over time: ``viewcomp render`` builds
  it with ``tau`` for video). For ``paper`` the model changes with the eye; the GL backend
  re-uploads its ``Wc_inv``/``inv_lut``/``inv_lo``/``inv_hi`` only when ``p.model is not``
  the previous one (Compensation caches models). Grid and method stay fixed per file.
- ``eye_track``: callable ``t_seconds -> eye (3,)`` metres, or an
  :class:`~viewcomp.calib.world.audience.Audience` of several viewers (pixel method); see
  :mod:`viewcomp.rt.render.tracks`.
  Images use t = 0 for the eye and no time for ``comp`` (no smoothing).
- Thumbnails: images use ``viewcomp.calib.comp.compensation.thumbnail`` (area average); video
  frames :func:`viewcomp.rt.media.frames.thumbnail_planes` at the same size (nearest on the
  planes, cheap), identical for both backends.
- ``identity``: the very same decode/upload/shader/read-back/encode with compensation off;
  ``comp`` is not called (nothing to compensate).
- Images: any OpenCV-readable file in (8-bit RGB after decoding); out to ``.png``, ``.jpg``
  or ``.tif`` (8-bit RGB at the grid size). Videos: anything PyAV decodes; out to a video
  file (container from the extension, codec/profile/CRF/preset selectable, frame rate, frame
  count and audio kept) or an image sequence ``DIR/%05d.png`` (no audio). The formats and
  their checks: :mod:`viewcomp.rt.media.formats`.
- The output (extension, codec, profile, the grid's size, the encoder starting) is checked
  before the input is opened.
- Outputs are written to a temporary file (a temporary folder for a sequence) next to the
  output and renamed at the end; on any error nothing is left at (or next to) the output.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal, Protocol

import av
import numpy as np
from tqdm import tqdm

from viewcomp.calib.comp.compensation import THUMB_SIDE, thumbnail
from viewcomp.calib.errors import ImageError
from viewcomp.calib.io.imageio import read_rgb8
from viewcomp.calib.model.gamut import ToneField
from viewcomp.calib.model.reference import View, compensate
from viewcomp.calib.model.runtime import RuntimeModel
from viewcomp.calib.world.audience import Audience
from viewcomp.rt.media.encode_thread import EncodeThread
from viewcomp.rt.media.ffmpeg_pipe import FfmpegPipeWriter
from viewcomp.rt.media.formats import OutputPlan, plan_output
from viewcomp.rt.media.frames import Planes, fit_rgb, thumbnail_planes, yuv420p_to_rgb
from viewcomp.rt.media.images import ImageWriteError, SequenceWriter, write_still
from viewcomp.rt.media.video import (
    DEFAULT_PRESET,
    AudioItem,
    VideoReader,
    VideoWriter,
)
from viewcomp.rt.render.tracks import EyeTrack

Backend = Literal["gl", "cpu"]

IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp"}


class FrameParamsLike(Protocol):
    """What ``comp(thumb, eye, t)`` returns (``viewcomp.calib.comp.compensation.FrameParams``)."""

    model: RuntimeModel
    alpha: float
    beta: float


class CompensationLike(Protocol):
    """The per-frame parameters (``viewcomp.calib.comp.compensation.Compensation``)."""

    method: str

    @property
    def shape(self) -> tuple[int, int]: ...

    def base_model(self) -> RuntimeModel: ...

    def __call__(self, thumb: np.ndarray, eye: View, t: float | None = None) -> Any: ...


@dataclass(frozen=True)
class RenderStats:
    """What :func:`render_file` did.

    ``frames`` rendered in ``seconds`` wall time; ``startup_seconds`` until the first frame
    was handed to the encoder (context, shader compile, uploads, first decode);
    ``params_seconds`` spent in ``comp(thumb, eye, t)`` (thumbnail included).
    """

    kind: Literal["image", "video"]
    frames: int
    seconds: float
    startup_seconds: float = 0.0
    params_seconds: float = 0.0

    @property
    def fps(self) -> float:
        """Frames per second over the whole run (including start-up)."""
        return self.frames / self.seconds if self.seconds > 0 else float("inf")


def is_image(path: str | os.PathLike[str]) -> bool:
    """True when the path's extension is an image format (by name, not content)."""
    return Path(path).suffix.lower() in IMAGE_SUFFIXES


class _Engine:
    """Per-frame compensation with one backend; owns the Compensator for ``gl``.

    Per frame: :meth:`set_params` (recorded), :meth:`submit` (GL: upload and draw, which
    renders on the driver's threads; CPU: compute), :meth:`collect` (GL: wait, read back).
    Between submit and collect the caller may prepare the next frame's parameters.
    """

    def __init__(
        self,
        backend: Backend,
        model: RuntimeModel,
        identity: bool,
        ctx: Any,
    ) -> None:
        if backend not in ("gl", "cpu"):
            raise ValueError(f"backend must be 'gl' or 'cpu', got {backend!r}")
        self.backend = backend
        self.identity = identity
        self.model = model  # what the GL side holds
        self.next_model = model  # what the next submit uses
        self.ctx = ctx
        self.alpha, self.beta = 1.0, 0.0
        self.field: ToneField | None = None
        self.eye: View = np.asarray(model.cam_eye, np.float32)
        self.gl: Any = None
        self._result: np.ndarray | None = None
        if backend == "gl":
            self._make_gl(model)

    def _make_gl(self, model: RuntimeModel) -> None:
        from viewcomp.rt.gl.compensator import Compensator  # GL only when asked for

        if self.gl is not None:
            self.gl.release()
            self.gl = None
        self.gl = Compensator(model, self.ctx)
        self.gl.identity = self.identity

    def set_params(self, p: FrameParamsLike | None, eye: View) -> None:
        """The next frame's model, tone map (None: keep) and eye (or audience)."""
        if p is not None:
            model = p.model
            if model is not self.next_model and (
                model.shape != self.model.shape or model.method != self.model.method
            ):
                raise ValueError(
                    f"comp changed the grid or the method within one file: "
                    f"{self.model.method} {self.model.shape} -> {model.method} {model.shape}"
                )
            self.next_model = model
            self.alpha, self.beta = float(p.alpha), float(p.beta)
            self.field = getattr(p, "field", None)  # the adaptive tone map, or None
        self.eye = _view(eye)

    def submit(self, frame: np.ndarray | Planes) -> None:
        """Start compensating one frame (RGB or yuv420p planes, on the grid)."""
        model = self.next_model
        if self.gl is None:
            rgb = yuv420p_to_rgb(frame) if isinstance(frame, Planes) else frame
            self.model = model
            self._result = compensate(
                model, rgb, self.eye, self.alpha, self.beta, self.identity, field=self.field
            )
            return
        if model is not self.model:  # after the previous frame was read: no stall
            if model.method == "paper":
                self.gl.update_model(model.Wc_inv, model.inv_lut, model.inv_lo, model.inv_hi)
            else:  # a new per-pixel model: new maps, new compensator (not expected)
                self._make_gl(model)
            self.model = model
        if isinstance(self.eye, Audience):
            self.gl.set_audience(self.eye)
        else:
            self.gl.set_eye(*self.eye)
        self.gl.set_tone(self.alpha, self.beta)
        self.gl.set_field(self.field)
        if isinstance(frame, Planes):
            self.gl.upload_planes(frame)
        else:
            self.gl.upload(frame)
        self.gl.draw()

    def collect(self, out: np.ndarray | None = None) -> np.ndarray:
        """The submitted frame's result (H, W, 3) uint8 (into ``out`` if given)."""
        if self.gl is None:
            res, self._result = self._result, None
            if res is None:
                raise RuntimeError("collect() without submit()")
            if out is None:
                return res
            np.copyto(out, res)
            return out
        return self.gl.read(out)

    def run(self, frame: np.ndarray | Planes, out: np.ndarray | None = None) -> np.ndarray:
        """submit + collect."""
        self.submit(frame)
        return self.collect(out)

    def release(self) -> None:
        if self.gl is not None:
            self.gl.release()
            self.gl = None


def _view(eye: View) -> View:
    """A track's value for both backends: one eye as float32 (3,) (an audience of one too),
    a larger audience as it is."""
    if isinstance(eye, Audience):
        return eye if len(eye) > 1 else np.asarray(eye.eyes[0], np.float32)
    return np.asarray(eye, np.float32)


def _check_comp(comp: CompensationLike) -> RuntimeModel:
    """The base model of ``comp``, checked against its declared grid and method."""
    missing = [a for a in ("shape", "method", "base_model") if not hasattr(comp, a)]
    if missing or not callable(comp):
        raise TypeError(
            "comp must be a viewcomp.calib.comp.compensation.Compensation (or act like one: "
            "shape, method, base_model(), __call__(thumb, eye, t)); "
            f"{type(comp).__name__} lacks {missing or ['__call__']}"
        )
    model = comp.base_model()
    if not isinstance(model, RuntimeModel):
        raise TypeError(f"comp.base_model() must return a RuntimeModel, got {type(model)}")
    if tuple(model.shape) != tuple(comp.shape) or model.method != comp.method:
        raise ValueError(
            f"comp says {comp.method} on {tuple(comp.shape)} but its base model is "
            f"{model.method} on {model.shape}"
        )
    return model


def render_file(
    comp: CompensationLike,
    input_path: str | os.PathLike[str],
    output_path: str | os.PathLike[str],
    eye_track: EyeTrack,
    backend: Backend = "gl",
    identity: bool = False,
    crf: float = 18,
    codec: str | None = None,
    preset: str = DEFAULT_PRESET,
    progress: bool = True,
    ctx: Any = None,
    profile: str | None = None,
) -> RenderStats:
    """Compensate an image or a video file for the projector (see the module docstring).

    Args:
        comp: the frame parameters (a ``Compensation`` for one calibration and method).
        input_path: image (by extension, :data:`IMAGE_SUFFIXES`) or video.
        output_path: ``.png``/``.jpg``/``.tif`` for an image; for a video a video file
            (``.mp4``, ``.mov``, ``.mkv``, ``.webm``) or an image sequence ``DIR/%05d.png``.
        eye_track: ``t_seconds -> eye (3,)`` metres.
        backend: ``"gl"`` (shader, default) or ``"cpu"`` (numpy reference).
        identity: run the same pipeline with compensation off (``comp`` is not called).
        crf, codec, preset, profile: video encoder settings (the container's default codec,
            H.264 but for .webm (VP9); CRF 18; preset ``veryfast`` for libx264/libx265;
            the codec's default profile, e.g. ProRes 422 HQ).
        progress: show a tqdm bar with frames per second (stderr).
        ctx: an existing moderngl context for the GL backend (else one is made and freed).

    Returns:
        RenderStats (frames rendered, wall seconds, start-up, time in ``comp``).

    Raises:
        FormatError: an output whose extension, codec, profile or size cannot work (before
            the input is opened; the message lists the working pairings).
        VideoError / ImageError: unreadable input or unwritable output (nothing left behind).
        GLUnavailable: ``backend="gl"`` without a usable OpenGL 3.3 (EGL) driver.
        ValueError / TypeError: ``comp`` is not usable (wrong kind, inconsistent model).
    """
    t_start = time.perf_counter()
    if backend not in ("gl", "cpu"):
        raise ValueError(f"backend must be 'gl' or 'cpu', got {backend!r}")
    model = _check_comp(comp)
    src, dst = Path(input_path), Path(output_path)
    plan = plan_output(dst, is_image(src), codec, profile)  # before the input is opened
    plan.check_size(model.shape[1], model.shape[0])
    if is_image(src):
        frame = _read_image(src, model.shape)
        eye0 = _view(eye_track(0.0))
        t_params = 0.0
        eng = _Engine(backend, model, identity, ctx)
        try:
            params = None
            if not identity:
                t = time.perf_counter()
                params = comp(thumbnail(frame), eye0)
                t_params = time.perf_counter() - t
            eng.set_params(params, eye0)
            out = eng.run(frame)
        finally:
            eng.release()
        _write_image(dst, out)
        seconds = time.perf_counter() - t_start
        return RenderStats("image", 1, seconds, seconds, t_params)
    return _render_video(
        comp, model, src, plan, eye_track, backend, identity, crf, preset, progress, ctx, t_start
    )


def _render_video(
    comp: CompensationLike,
    model: RuntimeModel,
    src: Path,
    plan: OutputPlan,
    eye_track: EyeTrack,
    backend: Backend,
    identity: bool,
    crf: float,
    preset: str,
    progress: bool,
    ctx: Any,
    t_start: float,
) -> RenderStats:
    h, w = model.shape
    clock = {"params": 0.0, "first": None}

    with VideoReader(src, fit=(w, h)) as reader:
        info = reader.info
        eng = _Engine(backend, model, identity, ctx)
        try:
            writer = _writer(plan, reader, crf, preset)
            with EncodeThread(writer, (h, w, 3)) as enc:
                reader.audio_mode = writer.audio_mode
                bar = tqdm(
                    total=info.frames,
                    unit="frame",
                    disable=not progress,
                    desc=src.name,
                    dynamic_ncols=True,
                )
                try:
                    _video_loop(reader, comp, eng, enc, eye_track, identity, bar, clock, t_start)
                finally:
                    bar.close()
            frames = enc.frames_written
        finally:
            eng.release()
    seconds = time.perf_counter() - t_start
    first = clock["first"]
    return RenderStats("video", frames, seconds, first or seconds, clock["params"])  # type: ignore[arg-type]


def _writer(
    plan: OutputPlan, reader: VideoReader, crf: float, preset: str
) -> VideoWriter | SequenceWriter | FfmpegPipeWriter:
    """The writer for the plan: numbered images, the ffmpeg program (HAP) or PyAV."""
    info = reader.info
    w, h = reader.fit if reader.fit is not None else (info.width, info.height)
    if plan.kind == "sequence":
        return SequenceWriter(plan.path)
    assert plan.codec is not None
    if plan.codec.via_ffmpeg:
        src = info.path if reader.audio_stream is not None else None
        # ffmpeg puts the file's earliest timestamp at 0; the video's start is shifted to 0
        # here, so the audio moves by the difference (as VideoWriter's audio_start does).
        first = reader.container.start_time
        shift = info.start - (first / av.time_base if first is not None else 0.0)
        return FfmpegPipeWriter(plan, w, h, info.rate, src, info.audio_codec, max(shift, 0.0))
    return VideoWriter(plan.path, w, h, info.rate, crf=crf, colorspace=info.colorspace,
                       audio=reader.audio_stream, audio_start=info.start, preset=preset,
                       plan=plan)  # fmt: skip


def _video_loop(
    reader: VideoReader,
    comp: CompensationLike,
    eng: _Engine,
    enc: EncodeThread,
    eye_track: EyeTrack,
    identity: bool,
    bar: Any,
    clock: dict[str, Any],
    t_start: float,
) -> None:
    """Frames in order, one ahead: frame i renders while frame i+1's parameters are made.

    Audio items that arrive while a frame is in flight are queued after it, so the encoder
    sees everything in demux order.
    """
    in_flight: np.ndarray | None = None  # the buffer frame i is being rendered into
    audio: list[AudioItem] = []

    def deliver() -> None:
        nonlocal in_flight
        if in_flight is not None:
            enc.put_frame(eng.collect(in_flight))
            in_flight = None
            if clock["first"] is None:
                clock["first"] = time.perf_counter() - t_start
            bar.update(1)
        for a in audio:
            enc.put_audio(a)
        audio.clear()

    for item in reader:
        if isinstance(item, AudioItem):
            if in_flight is None:
                enc.put_audio(item)
            else:
                audio.append(item)
            continue
        eye = _view(eye_track(item.time))
        params = None
        if not identity:  # overlaps the previous frame's rendering
            t = time.perf_counter()
            params = comp(thumbnail_planes(item, THUMB_SIDE), eye, item.time)
            clock["params"] += time.perf_counter() - t
        buf = enc.buffer()
        deliver()
        eng.set_params(params, eye)
        eng.submit(item)
        in_flight = buf
    deliver()


def _read_image(path: Path, grid: tuple[int, int]) -> np.ndarray:
    """Read an image as 8-bit RGB (H, W, 3) fitted to ``grid`` (H, W)."""
    return fit_rgb(read_rgb8(path, ImageError), grid[1], grid[0])


def _write_image(path: Path, rgb: np.ndarray) -> None:
    """Write an 8-bit RGB PNG, JPEG or TIFF atomically (:func:`~viewcomp.rt.media.images.
    write_still`)."""
    try:
        write_still(path, rgb)
    except ImageWriteError as exc:
        raise ImageError(str(exc)) from exc
