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


# ------------------------------------------------------- the command line and live input


class UsageError(ViewcompError):
    """A command-line value that is wrong: the message says which and what is expected."""


class InputError(UsageError, ValueError):
    """A malformed or out-of-range value of a live eye or show-control command or of a
    command-line option; the message says what and what is expected."""


class EyeError(ViewcompError, ValueError):
    """A viewing angle, eye position or track outside the limits; names the value and fix."""


class AudienceError(EyeError):
    """An audience SPEC or a set of viewers that cannot be used; names the item and the fix."""


# ----------------------------------------------------------------------- the rig and its files


class GeometryError(ViewcompError, ValueError):
    """The rig's geometry cannot be used (a pixel misses the screen, a device behind it)."""


class RigError(ViewcompError, ValueError):
    """A rig.toml (or rig dict) that cannot be used; the message names file, key and fix."""


class InputFileError(ViewcompError, ValueError):
    """An input path that is not a usable file; the message names it, the cause and the fix."""


class CaptureError(ViewcompError, ValueError):
    """An image or capture set that cannot be used; the message names the file and the fix."""


class BundleError(ViewcompError, ValueError):
    """A calibration bundle that cannot be used; the message names file, cause and fix."""


class DeviceError(CaptureError):
    """A projector or camera that cannot be opened or used; the message says what to do."""


class FrameError(DeviceError):
    """One failed read (a dropped USB transfer, a timeout): the device itself is still usable,
    so the procedure may try again."""


# ----------------------------------------------------------------------- the simulator


class SimulatorError(ViewcompError, ValueError):
    """A simulator parameter is out of range or unknown."""


class MaterialError(ViewcompError, ValueError):
    """A material file (or array set) that cannot be used: the message names the file, what is
    wrong and what to do."""


# ------------------------------------------ run time: GL, media, rendering, export, live use


class ShaderError(ViewcompError, RuntimeError):
    """A shader failed to load, compile or link; the message names file, stage and line."""


class GLUnavailable(ViewcompError, RuntimeError):
    """No OpenGL 3.3 context can be made; the message names the cause and the fix."""


class VideoError(ViewcompError, RuntimeError):
    """A video cannot be read or written; the message names the file and the fix."""


class AudioDeviceError(ViewcompError, RuntimeError):
    """The audio device failed while playing; the player goes on silently."""


class TrackError(EyeError):
    """An angle track (CSV) is malformed; the message names the file, the line and the fix."""


class ImageError(ViewcompError, RuntimeError):
    """An input image cannot be read or the output image cannot be written."""


class ExportError(UsageError, ValueError):
    """An mpv shader cannot be made with these settings; the message says why and the fix.
    The settings are the command's options, so the command line refuses it as a bad option."""


class MpvCheckError(ViewcompError, RuntimeError):
    """The check could not run (no mpv, no display, no shader file); the message says why."""


class XvfbError(ViewcompError, RuntimeError):
    """Xvfb is missing or did not start; the message says why."""


class DetectorError(ViewcompError, RuntimeError):
    """The face model cannot be loaded; the message says what is missing."""


class SourceError(ViewcompError, ValueError):
    """A camera, video or image sequence that cannot be read; the message names it and says
    what to give instead."""
