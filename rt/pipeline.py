"""Headless rendering of an image or a video through the compensation (``viewcomp render``).

One function, :func:`render_file`, for both backends and for images and videos::

    decode (worker thread) -> fit to the grid -> thumbnail -> tone(thumb) -> (alpha, beta)
        -> eye = eye_track(t) -> model = model_provider(eye)
        -> compensate (GL Compensator, or viewcomp.calib.reference.compensate)
        -> encode (PNG, or PyAV video with the audio carried over)

Interfaces decided here (for the CLI wiring):

- ``model_provider``: a :class:`RuntimeModel`, or a callable ``eye (3,) -> RuntimeModel``
  called once per frame. For ``paper`` it returns the model whose ``Wc_inv``/``inv_lut``/
  ``inv_lo``/``inv_hi`` fit that eye (cache it; return the *same object* while nothing
  changed: the GL backend re-uploads those only when the object changes). The per-pixel
  arrays and the grid must stay the same for the whole file.
- ``eye_track``: callable ``t_seconds -> eye (3,)`` metres; see :mod:`viewcomp.rt.tracks`
  (constant angle/eye, or a CSV of (seconds, degrees)). Images use t = 0.
- ``tone``: callable ``thumbnail (h, w, 3) uint8 -> (alpha, beta)`` called once per frame in
  order (it may smooth over time); None means (1, 0). The thumbnail is the frame as the
  compensator sees it (after fitting; for video after the shared yuv -> RGB conversion),
  longest side ~64 pixels; both backends compute it identically.
- ``identity``: the very same pipeline with compensation switched off (A/B and timing).
- Images: any OpenCV-readable file in (8-bit RGB after decoding); the output must be ``.png``
  (8-bit RGB at the grid size). Videos: anything PyAV decodes; output container from the
  extension, codec/crf selectable, frame rate, frame count and audio kept.
- Outputs are written to a temporary file next to the output and renamed at the end; on any
  error nothing is left at (or next to) the output path.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import cv2
import numpy as np
from tqdm import tqdm

from viewcomp.calib.reference import RuntimeModel, compensate
from viewcomp.rt.frames import (
    Planes,
    fit_rgb,
    thumbnail_planes,
    thumbnail_rgb,
    yuv420p_to_rgb,
)
from viewcomp.rt.tracks import EyeTrack
from viewcomp.rt.video import AudioItem, VideoReader, VideoWriter, temp_path_for

Backend = Literal["gl", "cpu"]
ModelProvider = RuntimeModel | Callable[[np.ndarray], RuntimeModel]
Tone = Callable[[np.ndarray], tuple[float, float]]

IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp"}


class ImageError(RuntimeError):
    """An input image cannot be read or the output image cannot be written."""


@dataclass(frozen=True)
class RenderStats:
    """What :func:`render_file` did: ``frames`` rendered in ``seconds`` wall time."""

    kind: Literal["image", "video"]
    frames: int
    seconds: float

    @property
    def fps(self) -> float:
        """Frames per second over the whole run (including start-up)."""
        return self.frames / self.seconds if self.seconds > 0 else float("inf")


def is_image(path: str | os.PathLike[str]) -> bool:
    """True when the path's extension is an image format (by name, not content)."""
    return Path(path).suffix.lower() in IMAGE_SUFFIXES


class _Backend:
    """Per-frame compensation with one backend; owns the Compensator for ``gl``."""

    def __init__(self, backend: Backend, model: RuntimeModel, identity: bool, ctx: object):
        if backend not in ("gl", "cpu"):
            raise ValueError(f"backend must be 'gl' or 'cpu', got {backend!r}")
        self.backend = backend
        self.identity = identity
        self.model = model
        self.comp = None
        if backend == "gl":
            from viewcomp.rt.compensator import Compensator  # GL only when asked for

            self.comp = Compensator(model, ctx)  # type: ignore[arg-type]
            self.comp.identity = identity
            h, w = model.shape
            self.out = np.empty((h, w, 3), np.uint8)

    def set_model(self, model: RuntimeModel) -> None:
        if model is self.model:
            return
        if model.shape != self.model.shape or model.method != self.model.method:
            raise ValueError("model_provider changed the grid or the method within one file")
        self.model = model
        if self.comp is not None and model.method == "paper":
            self.comp.update_model(model.Wc_inv, model.inv_lut, model.inv_lo, model.inv_hi)

    def run(self, frame: np.ndarray | Planes, eye: np.ndarray, alpha: float, beta: float):
        if self.comp is None:
            rgb = yuv420p_to_rgb(frame) if isinstance(frame, Planes) else frame
            return compensate(self.model, rgb, eye, alpha, beta, identity=self.identity)
        self.comp.set_eye(*eye)
        self.comp.set_tone(alpha, beta)
        if isinstance(frame, Planes):
            return self.comp.render_planes(frame, out=self.out)
        return self.comp.render(frame, out=self.out)

    def release(self) -> None:
        if self.comp is not None:
            self.comp.release()


def render_file(
    model_provider: ModelProvider,
    input_path: str | os.PathLike[str],
    output_path: str | os.PathLike[str],
    eye_track: EyeTrack,
    backend: Backend = "gl",
    identity: bool = False,
    crf: float = 18,
    codec: str = "libx264",
    progress: bool = True,
    tone: Tone | None = None,
    ctx: object = None,
) -> RenderStats:
    """Compensate an image or a video file for the projector (see the module docstring).

    Args:
        model_provider: RuntimeModel, or ``eye -> RuntimeModel`` (per frame).
        input_path: image (by extension, :data:`IMAGE_SUFFIXES`) or video.
        output_path: ``.png`` for an image; a video container (``.mp4``, ``.mkv``) for video.
        eye_track: ``t_seconds -> eye (3,)`` metres.
        backend: ``"gl"`` (shader, default) or ``"cpu"`` (numpy reference).
        identity: run the same pipeline with compensation off.
        crf, codec: video encoder settings (H.264 via libx264, CRF 18 by default).
        progress: show a tqdm bar with frames per second (stderr).
        tone: ``thumbnail -> (alpha, beta)``; None = (1, 0).
        ctx: an existing moderngl context for the GL backend (else one is made and freed).

    Returns:
        RenderStats (frames rendered, wall seconds).

    Raises:
        VideoError / ImageError: unreadable input or unwritable output (nothing left behind).
        GLUnavailable: ``backend="gl"`` without a usable OpenGL 3.3 (EGL) driver.
    """
    t_start = time.perf_counter()
    provider: Callable[[np.ndarray], RuntimeModel]
    if isinstance(model_provider, RuntimeModel):
        const = model_provider
        provider = lambda eye: const  # noqa: E731
    else:
        provider = model_provider
    tone_fn: Tone = tone if tone is not None else (lambda thumb: (1.0, 0.0))
    src, dst = Path(input_path), Path(output_path)
    eye0 = np.asarray(eye_track(0.0), np.float32)
    model = provider(eye0)
    if is_image(src):
        if dst.suffix.lower() != ".png":
            raise ImageError(f"image output must be a .png file, got {dst}")
        frame = _read_image(src, model.shape)
        eng = _Backend(backend, model, identity, ctx)
        try:
            alpha, beta = tone_fn(thumbnail_rgb(frame))
            out = eng.run(frame, eye0, alpha, beta)
        finally:
            eng.release()
        _write_png(dst, out)
        return RenderStats("image", 1, time.perf_counter() - t_start)
    return _render_video(provider, model, src, dst, eye_track, backend, identity, crf, codec,
                         progress, tone_fn, ctx, t_start)  # fmt: skip


def _render_video(
    provider: Callable[[np.ndarray], RuntimeModel],
    model: RuntimeModel,
    src: Path,
    dst: Path,
    eye_track: EyeTrack,
    backend: Backend,
    identity: bool,
    crf: float,
    codec: str,
    progress: bool,
    tone: Tone,
    ctx: object,
    t_start: float,
) -> RenderStats:
    h, w = model.shape
    with VideoReader(src, fit=(w, h)) as reader:
        info = reader.info
        eng = _Backend(backend, model, identity, ctx)
        try:
            with VideoWriter(dst, w, h, info.rate, codec=codec, crf=crf,
                             colorspace=info.colorspace, audio=reader.audio_stream,
                             audio_start=info.start) as writer:  # fmt: skip
                reader.audio_mode = writer.audio_mode
                bar = tqdm(total=info.frames, unit="frame", disable=not progress,
                           desc=src.name, dynamic_ncols=True)  # fmt: skip
                try:
                    for item in reader:
                        if isinstance(item, AudioItem):
                            writer.write_audio(item)
                            continue
                        eye = np.asarray(eye_track(item.time), np.float32)
                        eng.set_model(provider(eye))
                        alpha, beta = tone(thumbnail_planes(item))
                        writer.write(eng.run(item, eye, alpha, beta))
                        bar.update(1)
                finally:
                    bar.close()
                frames = writer.frames_written
        finally:
            eng.release()
    return RenderStats("video", frames, time.perf_counter() - t_start)


def _read_image(path: Path, grid: tuple[int, int]) -> np.ndarray:
    """Read an image as 8-bit RGB (H, W, 3) fitted to ``grid`` (H, W)."""
    if not path.is_file():
        raise ImageError(f"cannot read image {path}: no such file")
    data = np.fromfile(path, np.uint8)
    bgr = cv2.imdecode(data, cv2.IMREAD_COLOR)
    if bgr is None:
        raise ImageError(
            f"cannot read image {path}: not a decodable image; fix: save it as PNG or JPEG"
        )
    rgb = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
    return fit_rgb(rgb, grid[1], grid[0])


def _write_png(path: Path, rgb: np.ndarray) -> None:
    """Write an 8-bit RGB PNG atomically (temporary file, then rename)."""
    ok, buf = cv2.imencode(".png", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    if not ok:
        raise ImageError(f"cannot encode PNG for {path}")
    tmp = temp_path_for(path)
    try:
        tmp.write_bytes(buf.tobytes())
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise ImageError(f"cannot write image {path}: {exc}") from exc
