"""The `viewcomp` command line: one sub-command per module in ``viewcomp.commands``."""

from __future__ import annotations

import argparse
import errno
import importlib
import sys
import traceback
from collections.abc import Sequence

from viewcomp import __version__
from viewcomp.calib.errors import ViewcompError

# Order as shown in --help; each module has register(subparsers) and its run functions.
COMMANDS = (
    "patterns",
    "simulate",
    "capture",
    "calibrate",
    "render",
    "evaluate",
    "demo",
    "play",
    "export-mpv",
)

DESCRIPTION = """\
View-dependent compensation for projectors on coloured and glossy surfaces.

A typical session:
  viewcomp capture caps --camera 0 --monitor 1   project patterns, grab the camera
  viewcomp patterns pats --size 1280x720      ... or just the patterns to project
  viewcomp simulate caps                      ... or simulated captures, no hardware
  viewcomp calibrate caps -o screen.vcb       captures -> calibration bundle
  viewcomp render screen.vcb in.mp4 -o out.mp4 --angle 60
  viewcomp play screen.vcb clip.mp4 --osc 127.0.0.1:9000   fullscreen, live viewing angle
  viewcomp export-mpv screen.vcb -o comp.glsl --angle 60    a user shader for mpv
  viewcomp evaluate -o report                 the paper's Section 5, in simulation
  viewcomp demo                               all of the above on a built-in example
"""


def build_parser() -> argparse.ArgumentParser:
    """The full argument parser (sub-commands registered from their modules)."""
    parser = argparse.ArgumentParser(
        prog="viewcomp",
        description=DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"viewcomp {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in COMMANDS:
        importlib.import_module(f"viewcomp.commands.{name.replace('-', '_')}").register(sub)
    return parser


class UsageError(ViewcompError):
    """A command-line value that is wrong: the message says which and what is expected."""


# What to do about an operating-system error, by errno: these come from the machine (a full
# disk, a read-only folder, a broken link), not from a bug, so they are reported as refusals.
_OS_FIXES = {
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


def os_error_message(exc: OSError) -> str:
    """One line for an operating-system error: the file, the cause and what to do."""
    where = f" {exc.filename}" if exc.filename else ""
    cause = exc.strerror or str(exc)
    fix = _OS_FIXES.get(exc.errno or 0, "check the path and the disk")
    notes = "".join(f"; {n}" for n in getattr(exc, "__notes__", ()))
    return f"cannot use{where}: {cause}{notes} - {fix}"


BUG_NOTE = (
    "this is a bug in viewcomp, not a problem with your input: please report it with the "
    "command line and the traceback above"
)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status.

    0: done. 2: a refusal (a :class:`ViewcompError`, an operating-system error such as a
    full disk, or a bad option): one line naming the thing at fault and the fix, nothing
    written; a bad option (argparse's or a :class:`UsageError`) raises ``SystemExit(2)``
    as argparse does. 1: any other exception, which is a bug: its traceback and a note asking to
    report it. 130: interrupted (Ctrl-C); partial outputs are removed as for an error.
    """
    parser = build_parser()
    args = parser.parse_args(argv)
    name = f"viewcomp {args.command}"
    try:
        return int(args.run(args) or 0)
    except UsageError as e:  # like argparse's own errors: SystemExit(2)
        parser.exit(2, f"{name}: error: {e}\n")
    except ViewcompError as e:
        print(f"{name}: error: {e}", file=sys.stderr)
        return 2
    except OSError as e:
        print(f"{name}: error: {os_error_message(e)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"{name}: interrupted", file=sys.stderr)
        return 130
    except Exception:
        traceback.print_exc()
        print(f"{name}: internal error: {BUG_NOTE}", file=sys.stderr)
        return 1
