"""The `viewcomp` command line: one sub-command per module in ``viewcomp.commands``."""

from __future__ import annotations

import argparse
import importlib
import sys
import traceback
from collections.abc import Sequence

from viewcomp import __version__
from viewcomp.calib.errors import ViewcompError, describe_os_error

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
        print(f"{name}: error: {describe_os_error(e)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"{name}: interrupted", file=sys.stderr)
        return 130
    except Exception:
        traceback.print_exc()
        print(f"{name}: internal error: {BUG_NOTE}", file=sys.stderr)
        return 1
