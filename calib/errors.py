"""The errors viewcomp raises for bad input: each message names the thing at fault and the fix.

Every refusal of an input, an option or an output derives from :class:`ViewcompError`; the
command line catches exactly these (exit status 2, the message alone). Any other exception
is a bug in viewcomp: the command line prints its traceback with a note asking to report it
(exit status 1).
"""

from __future__ import annotations

import errno
import os


class ViewcompError(Exception):
    """A bad input, option or output, refused before anything is lost.

    The message names the file, option or value at fault, the cause and what to do.
    """


class FitError(ViewcompError, ValueError):
    """A fit that cannot succeed from these captures.

    ``capture`` names the capture at fault (e.g. ``"screen/ramp"``), ``reason`` says why and
    what to change.
    """

    def __init__(self, capture: str, reason: str) -> None:
        super().__init__(f"{capture}: {reason}")
        self.capture = capture
        self.reason = reason


class OutputError(ViewcompError, ValueError):
    """An output path that would overwrite an input, or that cannot be written."""


# What to do about an operating-system error, by errno: these come from the machine (a full
# disk, a read-only folder, a broken link), not from a bug, so they are reported as refusals.
OS_FIXES = {
    errno.ENOSPC: "free some space on that disk, or write somewhere else",
    errno.EDQUOT: "free some space within your disk quota, or write somewhere else",
    errno.EROFS: "the file system is read-only: write somewhere else",
    errno.EACCES: "check the permissions, or use a folder you can write to",
    errno.EPERM: "check the permissions, or use a folder you can write to",
    errno.ENOENT: "check the path (the folder must exist)",
    errno.ENOTDIR: "check the path: a part of it is a file, not a folder",
    errno.EISDIR: "give a file, not a folder",
    errno.ELOOP: "the path is a loop of symbolic links: fix or remove the link",
    errno.ENAMETOOLONG: "use a shorter path",
}


def describe_os_error(exc: OSError, name: str | os.PathLike[str] | None = None) -> str:
    """One line for an operating-system error: the file (``name``, else the error's own),
    the cause, any notes (e.g. a clean-up that failed as well) and what to do."""
    where = name if name is not None else exc.filename
    prefix = f"{where}: " if where else ""
    cause = exc.strerror or str(exc)
    fix = OS_FIXES.get(exc.errno or 0, "check the path and the disk")
    notes = "".join(f"; {n}" for n in getattr(exc, "__notes__", ()))
    return f"{prefix}{cause}{notes} - {fix}"


class PlayerError(ViewcompError, RuntimeError):
    """Playback cannot start (no display, no such monitor, empty playlist); says why."""
