"""Reading and writing capture images, and atomic file writes.

Conventions: images are numpy arrays (H, W, 3) in RGB order, row 0 at the top. OpenCV's BGR
order never leaves this module. *Raw* images are what the file holds: uint8 (0..255) or uint16
(0..65535) encoded camera values, or float32 linear light for ``.npy``. *Linear* images are
float32 (H, W, 3) in 0..1 camera units (see :mod:`viewcomp.calib.world.response`).
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import BinaryIO

import cv2
import numpy as np

from viewcomp.calib.world.response import Response, parse_response

IMAGE_SUFFIXES = (".png", ".tif", ".tiff", ".npy")


class CaptureError(ValueError):
    """An image or capture set that cannot be used; the message names the file and the fix."""


def _umask() -> int:
    """The process umask, read without changing it where /proc allows (Linux)."""
    status = Path("/proc/self/status")
    if status.is_file():
        for line in status.read_text().splitlines():
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_open(path: str | Path) -> Iterator[BinaryIO]:
    """Open a temporary file next to ``path`` for binary writing; on success it replaces
    ``path`` in one step (``os.replace``), on any error it is removed and ``path`` is left as
    it was. The parent folder must exist.
    """
    target = Path(path)
    fd, tmp_name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    tmp = Path(tmp_name)
    try:
        with os.fdopen(fd, "wb") as f:
            yield f
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; give the usual mode
        os.replace(tmp, target)
    except BaseException:  # undo on any failure, Ctrl-C included; then re-raise
        tmp.unlink(missing_ok=True)
        raise


def read_image(path: str | Path) -> np.ndarray:
    """The raw pixels of an image file as (H, W, 3) RGB.

    PNG/TIFF: uint8 or uint16 encoded values, as stored. ``.npy``: float32 linear values
    (read with ``allow_pickle=False``). Grayscale is promoted to 3 channels, alpha is dropped.
    Raises :class:`CaptureError` when the file is missing or cannot be decoded.
    """
    p = Path(path)
    if not p.is_file():
        raise CaptureError(f"not found: {p}")
    if p.suffix.lower() == ".npy":
        try:
            arr = np.load(p, allow_pickle=False)
        except (ValueError, OSError, EOFError) as exc:
            raise CaptureError(f"cannot decode {p} as a .npy array: {exc}") from None
        if not isinstance(arr, np.ndarray) or arr.dtype.kind != "f":
            raise CaptureError(
                f"cannot use {p}: a .npy capture must hold float linear values, "
                f"got dtype {getattr(arr, 'dtype', type(arr).__name__)}"
            )
        arr = arr.astype(np.float32, copy=False)
        return _to_rgb(arr, p, bgr=False)
    try:
        data = np.fromfile(p, dtype=np.uint8)
    except OSError as exc:
        raise CaptureError(f"cannot read {p}: {exc}") from None
    img = cv2.imdecode(data, cv2.IMREAD_UNCHANGED) if data.size else None
    if img is None:
        raise CaptureError(
            f"cannot decode {p}: not a readable PNG or TIFF image (truncated or another format?)"
        )
    if img.dtype not in (np.uint8, np.uint16):
        raise CaptureError(
            f"cannot use {p}: PNG/TIFF captures must be 8- or 16-bit integers, got {img.dtype} "
            "(save linear float data as .npy instead)"
        )
    return _to_rgb(img, p, bgr=True)


def _to_rgb(img: np.ndarray, p: Path, *, bgr: bool) -> np.ndarray:
    if img.ndim == 2:
        img = img[:, :, None]
    if img.ndim != 3 or img.shape[2] not in (1, 2, 3, 4) or img.shape[0] == 0 or img.shape[1] == 0:
        raise CaptureError(
            f"cannot use {p}: expected an image (H, W), (H, W, 3) or (H, W, 4), got {img.shape}"
        )
    c = img.shape[2]
    if c in (1, 2):  # gray, gray + alpha
        out = np.repeat(img[:, :, :1], 3, axis=2)
    elif bgr:
        out = img[:, :, 2::-1]
    else:
        out = img[:, :, :3]
    return np.ascontiguousarray(out)


def to_linear(raw: np.ndarray, response: Response | str | float) -> np.ndarray:
    """Raw (H, W, 3) pixels -> float32 (H, W, 3) linear light, 0..1 camera units.

    uint8 is divided by 255, uint16 by 65535, then decoded by ``response``; float arrays
    (``.npy`` captures) are already linear and pass through as float32.
    """
    resp = response if isinstance(response, Response) else parse_response(response)
    if raw.dtype == np.uint8:
        return resp.decode(raw.astype(np.float32) / np.float32(255.0))
    if raw.dtype == np.uint16:
        return resp.decode(raw.astype(np.float32) / np.float32(65535.0))
    if raw.dtype.kind == "f":
        return raw.astype(np.float32, copy=False)
    raise ValueError(f"raw image must be uint8, uint16 or float, got {raw.dtype}")


def max_code_fraction(raw: np.ndarray) -> float:
    """Fraction of pixel-channels at the maximum code: 255 (uint8), 65535 (uint16), or >= 1.0
    for float linear images. A measure of saturation, 0..1."""
    if raw.size == 0:
        return 0.0
    if raw.dtype == np.uint8:
        return float(np.count_nonzero(raw == 255)) / raw.size
    if raw.dtype == np.uint16:
        return float(np.count_nonzero(raw == 65535)) / raw.size
    return float(np.count_nonzero(raw >= 1.0)) / raw.size


def write_png(path: str | Path, rgb: np.ndarray) -> None:
    """Write an (H, W, 3) RGB (or (H, W) gray) uint8 or uint16 array as a PNG, atomically.

    Values are written as given (encoded codes). ``path`` must end in ``.png``.
    """
    p = Path(path)
    if p.suffix.lower() != ".png":
        raise ValueError(f"write_png needs a .png path, got {p}")
    arr = np.asarray(rgb)
    if arr.dtype not in (np.uint8, np.uint16):
        raise ValueError(f"write_png needs uint8 or uint16 pixels, got {arr.dtype} for {p}")
    if arr.ndim == 3 and arr.shape[2] == 3:
        arr = arr[:, :, ::-1]
    elif arr.ndim != 2:
        raise ValueError(f"write_png needs an (H, W, 3) or (H, W) image, got {arr.shape} for {p}")
    ok, buf = cv2.imencode(".png", np.ascontiguousarray(arr))
    if not ok:
        raise CaptureError(f"cannot encode {p} as PNG")
    with atomic_open(p) as f:
        f.write(buf.tobytes())


def write_npy(path: str | Path, arr: np.ndarray) -> None:
    """Write an array as ``.npy`` (no pickle; object dtypes are refused), atomically."""
    a = np.asarray(arr)
    if a.dtype.hasobject:
        raise ValueError(f"write_npy refuses object arrays (they would need pickle): {path}")
    with atomic_open(path) as f:
        np.lib.format.write_array(f, a, allow_pickle=False)
