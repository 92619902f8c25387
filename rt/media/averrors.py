"""FFmpeg's errors in plain words: what went wrong with a media file and what to do.

PyAV raises FFmpeg's errors with FFmpeg's codes (``[Errno 1094995529] Invalid data found
when processing input``); :func:`describe_av_error` turns one into a cause a person can act
on. An MP4/MOV whose index (the ``moov`` box) is missing, the usual state of a file still
being recorded or cut short by a copy, is recognised by walking the file's top-level boxes
(a few reads of 16 bytes, no decoding), and reported as an incomplete file.
"""

from __future__ import annotations

import errno
import struct
from pathlib import Path

import av

INCOMPLETE_FIX = "was it still being written? re-encode it or copy it again"
DAMAGED_FIX = (
    "check that it is a complete video file FFmpeg can decode (`ffprobe FILE`), or re-encode "
    "it, e.g. `ffmpeg -i FILE -c:v libx264 -pix_fmt yuv420p -c:a aac fixed.mp4`"
)
_MAX_BOXES = 4096  # top-level boxes walked at most (real files have a handful)


def mp4_missing_index(path: Path) -> bool:
    """True when ``path`` starts like an MP4/MOV (an ``ftyp`` box), its top-level boxes are
    boxes (printable four-letter types) and none of them is the index (``moov``): a file cut
    short, or still being written."""
    try:
        size = path.stat().st_size
        with path.open("rb") as f:
            pos, seen_ftyp = 0, False
            for _ in range(_MAX_BOXES):
                if pos + 8 > size:
                    break
                f.seek(pos)
                head = f.read(16)
                box_size, kind = struct.unpack(">I4s", head[:8])
                if not all(32 <= ch < 127 for ch in kind):
                    return False  # not a box type: damaged data, not a cut-short file
                if kind == b"moov":
                    return False
                seen_ftyp = seen_ftyp or kind == b"ftyp"
                if box_size == 1 and len(head) == 16:  # a 64-bit size follows the type
                    box_size = struct.unpack(">Q", head[8:16])[0]
                elif box_size == 0:  # the box runs to the end of the file
                    break
                if box_size < 8:
                    break  # not a box structure: let FFmpeg's own verdict stand
                pos += box_size
            return seen_ftyp
    except OSError:
        return False


def describe_av_error(exc: BaseException, path: Path | None = None) -> tuple[str, str]:
    """(cause, fix) for an error PyAV raised while reading ``path``, in plain words.

    The cause never shows FFmpeg's numeric codes; the fix says what to do.
    """
    if path is not None and path.suffix.lower() in (".mp4", ".m4v", ".mov", ".m4a"):
        if isinstance(exc, (av.error.InvalidDataError, av.FFmpegError)) and mp4_missing_index(path):
            return "the file is incomplete (no index)", INCOMPLETE_FIX
    if isinstance(exc, av.error.InvalidDataError):
        return "FFmpeg cannot make sense of its data (damaged, or not a video)", DAMAGED_FIX
    if isinstance(exc, av.FFmpegError):
        code = exc.errno
        if code is not None and code in errno.errorcode:  # a system error, e.g. EACCES
            return exc.strerror or str(code), DAMAGED_FIX
        return (exc.strerror or type(exc).__name__).rstrip("."), DAMAGED_FIX
    if isinstance(exc, OSError):
        return exc.strerror or str(exc), DAMAGED_FIX
    return str(exc), DAMAGED_FIX
