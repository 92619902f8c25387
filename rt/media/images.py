"""Image files out: one still (PNG, JPEG, TIFF) or a numbered image sequence, atomically.

- :func:`write_still`: an (H, W, 3) uint8 RGB picture to ``.png``, ``.jpg``/``.jpeg``
  (quality 95, no chroma subsampling: the compensated picture's colour edges matter) or
  ``.tif``/``.tiff`` (lossless, LZW), 8 bits a channel, written to a temporary file and
  renamed into place.
- :class:`SequenceWriter`: frames to ``DIR/%05d.png`` (or ``.jpg``/``.tif``), numbered from 0,
  written into a hidden temporary folder next to ``DIR`` that becomes ``DIR`` only when every
  frame is written (:func:`viewcomp.calib.io.atomic.atomic_dir`); on an error or
  :meth:`~SequenceWriter.abort` nothing is left. It has :class:`~viewcomp.rt.media.video.
  VideoWriter`'s interface, so :class:`~viewcomp.rt.media.video.EncodeThread` runs it; image
  sequences carry no audio (``audio_mode = "none"``).
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from viewcomp.calib.errors import ViewcompError, describe_os_error
from viewcomp.calib.io.atomic import atomic_dir, atomic_path
from viewcomp.rt.media.video import AudioMode

# OpenCV's writer parameters per extension: JPEG quality 95 at 4:4:4, TIFF LZW (lossless).
_JPEG = [
    cv2.IMWRITE_JPEG_QUALITY,
    95,
    cv2.IMWRITE_JPEG_SAMPLING_FACTOR,
    cv2.IMWRITE_JPEG_SAMPLING_FACTOR_444,
]
_TIFF = [cv2.IMWRITE_TIFF_COMPRESSION, 5]  # 5: LZW
_PARAMS = {".png": [], ".jpg": _JPEG, ".jpeg": _JPEG, ".tif": _TIFF, ".tiff": _TIFF}


class ImageWriteError(ViewcompError, RuntimeError):
    """An output image (a still or a frame of a sequence) cannot be written."""


def encode_image(rgb: np.ndarray, suffix: str) -> bytes:
    """An (H, W, 3) uint8 RGB array encoded as ``suffix`` (``.png``, ``.jpg``, ``.tif``)."""
    params = _PARAMS.get(suffix.lower())
    if params is None:
        raise ValueError(f"no image format for {suffix!r}: use one of {', '.join(_PARAMS)}")
    arr = np.asarray(rgb)
    if arr.dtype != np.uint8 or arr.ndim != 3 or arr.shape[2] != 3:
        raise ValueError(f"expected an (H, W, 3) uint8 RGB image, got {arr.dtype} {arr.shape}")
    ok, buf = cv2.imencode(suffix.lower(), np.ascontiguousarray(arr[:, :, ::-1]), params)
    if not ok:
        raise ImageWriteError(f"OpenCV cannot encode a {arr.shape} image as {suffix}")
    return buf.tobytes()


def write_still(path: str | os.PathLike[str], rgb: np.ndarray) -> None:
    """Write one (H, W, 3) uint8 RGB picture as PNG, JPEG or TIFF (by extension), atomically.

    Raises ImageWriteError naming the file and the fix when it cannot be written.
    """
    p = Path(path)
    data = encode_image(rgb, p.suffix)
    try:
        with atomic_path(p) as tmp:
            tmp.write_bytes(data)
    except OSError as exc:
        raise ImageWriteError(f"cannot write image {describe_os_error(exc, p)}") from exc


class SequenceWriter:
    """Frames to numbered images ``pattern % index`` (index from 0) in a folder, atomically.

    Args:
        pattern: ``DIR/%05d.png`` (a printf frame number; ``.png``/``.jpg``/``.tif``). DIR
            must be absent or empty (checked by :func:`viewcomp.rt.media.formats.plan_output`).

    :meth:`write` takes (H, W, 3) uint8 RGB; :meth:`close` makes DIR appear whole,
    :meth:`abort` leaves nothing. ``write_audio`` ignores audio.
    """

    audio_mode: AudioMode = "none"

    def __init__(self, pattern: str | os.PathLike[str]) -> None:
        self.pattern = Path(pattern)
        self.folder = self.pattern.parent
        self._index = 0
        self._done = False
        self._dir = atomic_dir(self.folder)
        try:
            self._tmp: Path = self._dir.__enter__()
        except OSError as exc:
            raise ImageWriteError(
                f"cannot write the image sequence {describe_os_error(exc, self.folder)}"
            ) from exc

    @property
    def frames_written(self) -> int:
        """Images written so far."""
        return self._index

    def write(self, rgb: np.ndarray) -> None:
        """Write the next frame as its numbered image."""
        name = self.pattern.name % self._index
        data = encode_image(rgb, self.pattern.suffix)
        try:
            (self._tmp / name).write_bytes(data)
        except OSError as exc:
            raise ImageWriteError(
                f"cannot write the image sequence {describe_os_error(exc, self.folder / name)}"
            ) from exc
        self._index += 1

    def write_audio(self, item: Any) -> None:
        """Image sequences have no audio: ignored."""

    def close(self) -> None:
        """Move the finished folder into place."""
        if self._done:
            return
        self._done = True
        try:
            self._dir.__exit__(None, None, None)
        except OSError as exc:
            raise ImageWriteError(
                f"cannot write the image sequence {describe_os_error(exc, self.folder)}"
            ) from exc

    def abort(self) -> None:
        """Remove the temporary folder; nothing is left at the output."""
        if self._done:
            return
        self._done = True
        exc = RuntimeError("aborted")
        with contextlib.suppress(RuntimeError):  # atomic_dir re-raises what it was given
            self._dir.__exit__(RuntimeError, exc, None)
