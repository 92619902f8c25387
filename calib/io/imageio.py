"""Reading and writing images, and turning encoded camera codes into linear light.

The one image reader of viewcomp (:func:`read_image` for captures as stored, :func:`read_rgb8`
for content such as a photo or a video frame) and the one linearisation (:func:`to_linear`).
Conventions: images are numpy arrays (H, W, 3) in RGB order, row 0 at the top. OpenCV's BGR
order never leaves this module. *Raw* images are what the file holds: uint8 (0..255) or uint16
(0..65535) encoded camera values, or float32 linear light for ``.npy``. *Linear* images are
float32 (H, W, 3) in 0..1 camera units (see :mod:`viewcomp.calib.world.response`).
"""

from __future__ import annotations

import functools
import io
import warnings
from pathlib import Path

import cv2
import numpy as np

from viewcomp.calib.errors import CaptureError, ViewcompError
from viewcomp.calib.io import npy
from viewcomp.calib.io.atomic import atomic_open
from viewcomp.calib.io.paths import check_input_file
from viewcomp.calib.world.response import Response, parse_response

IMAGE_SUFFIXES = (".png", ".tif", ".tiff", ".npy")
# The largest image read, checked in the file's header before decoding: 16384 pixels a
# side (the largest GL texture on common drivers) and 64 megapixels (8K video is 33).
MAX_IMAGE_SIDE = 16384
MAX_IMAGE_PIXELS = 64_000_000


def read_image(path: str | Path) -> np.ndarray:
    """The raw pixels of an image file as (H, W, 3) RGB.

    PNG/TIFF: uint8 or uint16 encoded values, as stored. ``.npy``: float32 linear values
    (read with ``allow_pickle=False``). Grayscale is promoted to 3 channels, alpha is dropped.
    Raises :class:`CaptureError` when the file is missing or cannot be decoded.
    """
    p = Path(path)
    _check_file(p)
    if p.suffix.lower() == ".npy":
        return _to_rgb(_read_npy(p), p, bgr=False)
    img = _decode(p, cv2.IMREAD_UNCHANGED, "a PNG or TIFF image")
    if img.dtype not in (np.uint8, np.uint16):
        raise CaptureError(
            f"cannot use {p}: PNG/TIFF captures must be 8- or 16-bit integers, got {img.dtype} "
            "(save linear float data as .npy instead)"
        )
    return _to_rgb(img, p, bgr=True)


def read_rgb8(path: str | Path, error: type[ViewcompError] = CaptureError) -> np.ndarray:
    """An image to show (a photo, a video frame) as 8-bit RGB (H, W, 3) uint8.

    Any format OpenCV decodes (PNG, JPEG, TIFF, BMP, WebP); 16-bit images are scaled to 8 bits,
    gray is promoted to 3 channels, alpha is dropped. Raises ``error`` (:class:`CaptureError`
    unless the caller names its own, e.g. rendering's ImageError) when the file is missing,
    empty or cannot be decoded.
    """
    p = Path(path)
    _check_file(p, error)
    bgr = _decode(p, cv2.IMREAD_COLOR, "an image (PNG or JPEG)", error)
    return np.ascontiguousarray(bgr[:, :, ::-1])


def _check_file(p: Path, error: type[ViewcompError] = CaptureError) -> None:
    check_input_file(p, "image", "an image file (saved or captured again if damaged)", error)


def _read_npy(p: Path) -> np.ndarray:
    """A ``.npy`` capture as float32, its header (dtype, size) checked before the data is
    read and its values checked after (finite)."""
    try:
        with p.open("rb") as f:
            shape, dtype = npy.read_header(f)
            if dtype.kind != "f":
                raise CaptureError(
                    f"cannot use {p}: a .npy capture must hold float linear values, got "
                    f"dtype {dtype} - save float32 linear light, or the capture as PNG"
                )
            _check_dimensions(p, shape[1] if len(shape) > 1 else 1, shape[0] if shape else 0)
            arr = npy.read_data(f, shape, dtype)
    except ValueError as exc:
        if isinstance(exc, CaptureError):
            raise
        raise CaptureError(f"cannot decode {p} as a .npy array: {exc} - save it again") from None
    arr = arr.astype(np.float32, copy=False)
    if not np.all(np.isfinite(arr)):
        bad = int(np.count_nonzero(~np.isfinite(arr)))
        raise CaptureError(
            f"cannot use {p}: {bad} value(s) are NaN or infinite - a .npy capture holds finite "
            "linear light; capture or save it again"
        )
    return arr


def _check_dimensions(p: Path, w: int, h: int, error: type[ViewcompError] = CaptureError) -> None:
    if w > MAX_IMAGE_SIDE or h > MAX_IMAGE_SIDE or w * h > MAX_IMAGE_PIXELS:
        raise error(
            f"cannot use {p}: its header says {w}x{h} pixels, over the limit of "
            f"{MAX_IMAGE_SIDE} pixels a side and {MAX_IMAGE_PIXELS / 1e6:.0f} megapixels - "
            "scale it down (or the file is damaged)"
        )


def _header_size(p: Path, data: np.ndarray) -> tuple[int, int] | None:
    """(width, height) from the image's header, read without decoding the pixels; None when
    the format's header is not understood (OpenCV's decoder then has the last word)."""
    head = data[:24].tobytes()
    if head[:8] == b"\x89PNG\r\n\x1a\n" and head[12:16] == b"IHDR":  # width, height at 16
        return int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")
    from PIL import Image

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # e.g. Pillow's own size warning
            with Image.open(io.BytesIO(data.tobytes())) as im:
                return im.size
    except Image.DecompressionBombError:
        return (MAX_IMAGE_SIDE + 1, MAX_IMAGE_SIDE + 1)
    except Exception:  # any header Pillow cannot read is left to OpenCV
        return None


def _decode(
    p: Path, flags: int, kind: str, error: type[ViewcompError] = CaptureError
) -> np.ndarray:
    """The pixels of an image file as OpenCV decodes them with ``flags`` (BGR order), after
    the header's dimensions are checked against the limits; else ``error``."""
    try:
        data = np.fromfile(p, dtype=np.uint8)
    except OSError as exc:
        raise error(f"cannot read image {p}: {exc}") from None
    if data.size == 0:
        raise error(
            f"cannot read image {p}: cannot decode an empty (0-byte) file; fix: save or "
            "capture it again"
        )
    size = _header_size(p, data)
    if size is not None:
        _check_dimensions(p, *size, error)
    img = cv2.imdecode(data, flags)
    if img is None:
        raise error(
            f"cannot read image {p}: cannot decode {p.name} as {kind} (truncated or another "
            "format?); fix: save it again as PNG"
        )
    return img


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
    if raw.dtype in (np.uint8, np.uint16):
        return _decode_table(resp, raw.dtype.str)[raw]
    if raw.dtype.kind == "f":
        return raw.astype(np.float32, copy=False)
    raise ValueError(f"raw image must be uint8, uint16 or float, got {raw.dtype}")


@functools.lru_cache(maxsize=8)
def _decode_table(response: Response, dtype: str) -> np.ndarray:
    """``response.decode(code / full scale)`` for every code of ``dtype`` (uint8 or uint16):
    looking codes up is exact and much faster than decoding each pixel."""
    top = np.iinfo(np.dtype(dtype)).max
    table = response.decode(np.arange(top + 1, dtype=np.float32) / np.float32(top))
    table.flags.writeable = False
    return table


def max_code_fraction(raw: np.ndarray) -> float:
    """Fraction of pixel-channels at the maximum code: 255 (uint8), 65535 (uint16). A measure
    of saturation, 0..1. Float linear images (``.npy``) have no maximum code: light above 1
    (the full scale of the base exposure) is what an HDR merge holds, not clipping, so they
    count as 0 (a bracket whose shortest frame clips is refused when it is captured)."""
    if raw.size == 0:
        return 0.0
    if raw.dtype == np.uint8:
        return float(np.count_nonzero(raw == 255)) / raw.size
    if raw.dtype == np.uint16:
        return float(np.count_nonzero(raw == 65535)) / raw.size
    return 0.0


def clipped_mask(raw: np.ndarray) -> np.ndarray:
    """(H, W) bool: pixels with a channel at the maximum code (255 for uint8, 65535 for
    uint16). Float captures are linear measurements (HDR merges included) and clip nowhere."""
    if raw.dtype == np.uint8:
        return np.any(raw == 255, axis=-1) if raw.ndim == 3 else raw == 255
    if raw.dtype == np.uint16:
        return np.any(raw == 65535, axis=-1) if raw.ndim == 3 else raw == 65535
    return np.zeros(raw.shape[:2], bool)


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
