"""Atomic file writes: the one way viewcomp writes an output file.

Every output is written to a hidden temporary file in the target's folder
(``.NAME.XXXXXXXX.partial.EXT``: same folder so the rename is atomic, same extension so
encoders that pick a format from the name still can). On success the file is flushed to disk
(``fsync``), renamed over the target in one step (``os.replace``) and the folder is synced so
the rename itself survives a power cut. On any failure (an exception, disk full, a read-only
folder, Ctrl-C) the temporary file is removed and the target keeps its old content, or stays
absent. The first error is the one raised: a clean-up that fails as well is added to it as a
note, never raised in its place.

- :func:`atomic_open`: a binary stream to write into (``with atomic_open(p) as f: ...``).
- :func:`atomic_path`: a temporary *path* for writers that need a file name (PyAV, OpenCV).
- :func:`write_bytes_atomic`, :func:`write_text_atomic`: one call for data held in memory.
- :class:`AtomicFile`: the same steps for writers whose start and end are separate calls
  (a video encoder's ``close``/``abort``).
- :func:`atomic_dir`: a whole folder (a capture set, the patterns): written into a hidden
  temporary folder next to it, which then replaces the old folder whole, so no file of an
  old set survives and a failure leaves the old folder as it was.

The target's folder must exist.
"""

from __future__ import annotations

import contextlib
import errno
import os
import shutil
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import BinaryIO

# Folder fsync is not supported everywhere (some network and FUSE file systems); there the
# rename is as durable as the file system makes it.
_NO_DIR_SYNC = {errno.EINVAL, errno.ENOTSUP, errno.EBADF, errno.EACCES, errno.EISDIR}


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


def _name_target(exc: BaseException | None, path: Path, tmp: Path | None = None) -> None:
    """Give an OSError without a file name (a write to a full disk), or with the temporary
    file's, the target's name, so that its message says which output failed."""
    if not isinstance(exc, OSError) or exc.errno is None:
        return  # not an error from the system: its message stays as it is
    if not exc.filename or str(exc.filename) == str(tmp):
        with contextlib.suppress(AttributeError):  # some subclasses' filename is read-only
            exc.filename = str(path)


def _fsync_dir(folder: Path) -> None:
    """Flush a folder's entries (a rename) to disk where the file system supports it."""
    flags = os.O_RDONLY | getattr(os, "O_DIRECTORY", 0)
    try:
        fd = os.open(folder, flags)
    except OSError as exc:
        if exc.errno in _NO_DIR_SYNC:
            return
        raise
    try:
        os.fsync(fd)
    except OSError as exc:
        if exc.errno not in _NO_DIR_SYNC:
            raise
    finally:
        os.close(fd)


class AtomicFile:
    """A temporary file next to ``path`` that becomes ``path`` on :meth:`commit`.

    Creating it creates the (empty) temporary file :attr:`tmp`; write it by name, then call
    exactly one of :meth:`commit` (fsync, rename over ``path``, fsync the folder) or
    :meth:`discard` (remove it). A failing :meth:`commit` discards before raising.

    Raises:
        OSError: the temporary file cannot be created (missing or read-only folder, disk
            full); the message names the folder.
    """

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        fd, name = tempfile.mkstemp(
            prefix=f".{self.path.name}.", suffix=f".partial{self.path.suffix}", dir=self.path.parent
        )
        os.close(fd)
        self.tmp = Path(name)
        self._done = False

    def commit(self) -> None:
        """Flush the temporary file to disk and rename it over :attr:`path` in one step."""
        if self._done:
            raise RuntimeError(f"{self.path}: the atomic write was already finished")
        try:
            with open(self.tmp, "rb") as f:
                os.fsync(f.fileno())
            os.chmod(self.tmp, 0o666 & ~_umask())  # mkstemp makes 0600; give the usual mode
            os.replace(self.tmp, self.path)
        except BaseException as exc:  # undo on any failure, Ctrl-C included; then re-raise
            self._cleanup(exc)
            raise
        self._done = True
        _fsync_dir(self.path.parent)

    def discard(self, cause: BaseException | None = None) -> None:
        """Remove the temporary file (the target is left as it was). Never raises: when the
        removal fails, the failure is added as a note to ``cause`` (the error being handled)."""
        if not self._done:
            self._cleanup(cause)

    def _cleanup(self, cause: BaseException | None) -> None:
        _name_target(cause, self.path, self.tmp)
        self._done = True
        try:
            self.tmp.unlink(missing_ok=True)
        except OSError as exc:
            if cause is not None:
                cause.add_note(f"the temporary file {self.tmp} could not be removed: {exc}")


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """A temporary path next to ``path`` (same extension) for a writer that needs a file
    name; when the block ends without an error the file there replaces ``path``.

    Example: ``with atomic_path(out) as tmp: cv2.imwrite(str(tmp), img)``.
    """
    target = AtomicFile(path)
    try:
        yield target.tmp
    except BaseException as exc:
        target.discard(exc)
        raise
    target.commit()


@contextlib.contextmanager
def atomic_open(path: str | os.PathLike[str]) -> Iterator[BinaryIO]:
    """A binary stream on a temporary file next to ``path``; when the block ends without an
    error it replaces ``path`` in one step, on any error it is removed and ``path`` is left as
    it was."""
    target = AtomicFile(path)
    try:
        with open(target.tmp, "wb") as f:
            yield f
    except BaseException as exc:
        target.discard(exc)
        raise
    target.commit()


def write_bytes_atomic(path: str | os.PathLike[str], data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""
    with atomic_open(path) as f:
        f.write(data)


def write_text_atomic(path: str | os.PathLike[str], text: str, encoding: str = "utf-8") -> None:
    """Write ``text`` to ``path`` atomically (encoded with ``encoding``)."""
    data = text.encode(encoding)  # an encoding error is raised before any file is made
    write_bytes_atomic(path, data)


def _remove_tree(folder: Path, cause: BaseException | None) -> None:
    """Remove ``folder`` and everything in it; a failure becomes a note on ``cause`` (the
    error being handled), or is ignored when there is none (the result is committed)."""
    errors: list[str] = []

    def record(_func: object, where: str, exc: object) -> None:
        errors.append(f"{where}: {exc[1] if isinstance(exc, tuple) else exc}")

    if sys.version_info >= (3, 12):
        shutil.rmtree(folder, onexc=record)
    else:  # Python 3.11 names the hook onerror (deprecated since 3.12)
        shutil.rmtree(folder, onerror=record)
    if errors and cause is not None:
        cause.add_note(f"the temporary folder {folder} could not be removed: {errors[0]}")


@contextlib.contextmanager
def atomic_dir(path: str | os.PathLike[str]) -> Iterator[Path]:
    """A temporary folder next to ``path`` to write a whole folder into; when the block ends
    without an error it replaces ``path`` (whole: nothing of an old folder survives), on any
    error it is removed and ``path`` is left as it was.

    The swap is two renames (old folder aside, new folder in place); a failure between them
    puts the old folder back. Files inside are best written with the other helpers here.
    The folder of ``path`` is created when missing.
    """
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".partial", dir=target.parent))
    try:
        yield tmp
        os.chmod(tmp, 0o777 & ~_umask())  # mkdtemp makes 0700; give the usual mode
        _fsync_dir(tmp)
        old = None
        if target.exists() or target.is_symlink():
            old = Path(
                tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".old", dir=target.parent)
            )
            os.replace(target, old / "old")
        try:
            os.replace(tmp, target)
        except BaseException:  # undo on any failure, Ctrl-C included; then re-raise
            if old is not None:
                os.replace(old / "old", target)
                _remove_tree(old, None)
            raise
    except BaseException as exc:
        if isinstance(exc, OSError) and str(exc.filename or "").startswith(f"{tmp}{os.sep}"):
            with contextlib.suppress(AttributeError):  # name the real file, not the temporary
                exc.filename = str(target / Path(exc.filename).relative_to(tmp))
        _name_target(exc, target)
        if tmp.exists():
            _remove_tree(tmp, exc)
        raise
    _fsync_dir(target.parent)
    if old is not None:
        _remove_tree(old, None)
