"""Checks of the paths a command reads and writes, made before any work is done.

- :func:`check_input_file`: an input file exists and is a non-empty regular file; a missing
  file, a folder, a broken link, a loop of links, a device and an empty file each get their
  own message naming the path and the fix.
- :func:`check_output`: an output never is, or resolves to (through symbolic or hard links),
  one of the command's inputs or lies inside an input folder; a file output is not a folder
  and its folder exists, a folder output is not a file.

Writing itself goes through :mod:`viewcomp.calib.io.atomic`; these checks only refuse.
"""

from __future__ import annotations

import errno
import os
import stat
from collections.abc import Iterable
from pathlib import Path

from viewcomp.calib.errors import InputFileError, OutputError, ViewcompError


def path_problem(p: Path) -> str | None:
    """Why ``p`` cannot be used at all ("not found", "is a loop of symbolic links", ...), or
    None when it exists (its kind is for the caller to check)."""
    try:
        p.stat()
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            return "is a loop of symbolic links"
        if exc.errno == errno.ENOENT:
            if p.is_symlink():
                return f"is a broken symbolic link (to {os.readlink(p)})"
            return "not found"
        if exc.errno == errno.ENOTDIR:
            return "not found (a part of the path is a file, not a folder)"
        return f"cannot be read ({exc.strerror})"
    return None


def check_input_file(
    path: str | os.PathLike[str],
    what: str,
    expected: str,
    error: type[ViewcompError] = InputFileError,
    empty_ok: bool = False,
) -> Path:
    """``path`` as a Path when it is a readable, non-empty regular file; else ``error``.

    ``what`` names the input (e.g. ``"image"``), ``expected`` says what to give instead
    (e.g. ``"a PNG or JPEG file"``); both go into the message.
    """
    p = Path(path)
    cause = path_problem(p)
    if cause is None:
        st = p.stat()
        if stat.S_ISDIR(st.st_mode):
            cause = "is a folder, not a file"
        elif not stat.S_ISREG(st.st_mode):
            cause = "is not a regular file (a device, pipe or socket)"
        elif st.st_size == 0 and not empty_ok:
            cause = "is empty (0 bytes)"
        elif not os.access(p, os.R_OK):
            cause = "cannot be read (permission denied)"
    if cause is not None:
        raise error(f"{what} {p}: {cause} - give {expected}")
    return p


def _same(a: Path, b: Path) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return a.resolve() == b.resolve()


def check_output(
    path: str | os.PathLike[str],
    inputs: Iterable[str | os.PathLike[str]] = (),
    *,
    folder: bool = False,
    make_parents: bool = False,
) -> Path:
    """``path`` as a Path when writing it cannot destroy an input; else :class:`OutputError`.

    Refused: an output that is an input (the same file through any link), an input folder or
    a path inside one; a file output that is an existing folder (``folder=False``) or whose
    folder does not exist (unless ``make_parents``: the writer creates it); a folder output
    that is an existing file or holds an input (``folder=True``); a loop of symbolic links.
    """
    out = Path(path)
    try:
        resolved = out.resolve()
    except (OSError, RuntimeError):
        raise OutputError(
            f"output {out}: is a loop of symbolic links - remove the link or choose another path"
        ) from None
    for item in inputs:
        src = Path(item)
        if not src.exists():
            continue
        src_resolved = src.resolve()
        if (out.exists() and _same(out, src)) or resolved == src_resolved:
            raise OutputError(
                f"output {out} is the input {src}: writing it would destroy the input - "
                "choose another output path"
            )
        if src.is_dir() and resolved.is_relative_to(src_resolved):
            raise OutputError(
                f"output {out} is inside the input folder {src}: writing there would change "
                "the input - choose a path outside it"
            )
        if folder and src_resolved.is_relative_to(resolved):
            raise OutputError(
                f"the input {src} is inside the output folder {out}, which would be written "
                "over - choose another output folder"
            )
        if not folder and out.is_dir() and _same(out, src.parent):
            raise OutputError(
                f"output {out} is the folder of the input {src}, not a file - give a file name"
            )
    if folder:
        if out.exists() and not out.is_dir():
            raise OutputError(
                f"output folder {out} is an existing file - give a folder path (new or empty)"
            )
        return out
    if out.is_dir():
        raise OutputError(f"output {out} is a folder - give a file name inside it")
    parent = resolved.parent
    if not parent.is_dir():
        if parent.exists():
            raise OutputError(f"output {out}: {parent} is a file, not a folder - fix the path")
        if not make_parents:
            raise OutputError(
                f"output {out}: the folder {out.parent} does not exist - create it first "
                f"(mkdir -p {out.parent}) or choose another path"
            )
    return out
