"""The `viewcomp` command line: one sub-command per module in ``viewcomp.commands``."""

from __future__ import annotations

import argparse
import importlib
import logging
import os
import re
import signal
import sys
import threading
import traceback
from collections.abc import Sequence
from typing import Any

from viewcomp import __version__
from viewcomp.calib.errors import UsageError, ViewcompError, describe_os_error

# Order as shown in --help; each module has register(subparsers) and its run functions.
COMMANDS = (
    "patterns",
    "simulate",
    "capture",
    "calibrate",
    "render",
    "preview",
    "evaluate",
    "demo",
    "play",
    "track",
    "export-mpv",
    "check-mpv",
)

DESCRIPTION = """\
View-dependent compensation for projectors on coloured and glossy surfaces.

A typical session:
  viewcomp capture caps --camera 0 --monitor 1   project patterns, grab the camera
  viewcomp patterns pats --size 1280x720      ... or just the patterns to project
  viewcomp simulate caps                      ... or simulated captures, no hardware
  viewcomp calibrate caps -o screen.vcb       captures -> calibration bundle
  viewcomp render screen.vcb in.mp4 -o out.mp4 --angle 60
  viewcomp preview screen.vcb photo.jpg -o seen.png --angle 60   what the audience sees
  viewcomp play screen.vcb clip.mp4 --osc 127.0.0.1:9000   fullscreen, live viewing angle
  viewcomp track --camera 0 --rig screen.vcb | viewcomp play ...  follow the viewer's face
  viewcomp export-mpv screen.vcb -o comp.glsl --angle 60    a user shader for mpv
  viewcomp check-mpv comp.glsl                does the installed mpv run it?
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


BUG_NOTE = (
    "this is a bug in viewcomp, not a problem with your input: please report it with the "
    "command line and the traceback above"
)


class _StderrHandler(logging.StreamHandler):  # type: ignore[type-arg]
    """Writes to the current ``sys.stderr`` (which tests and redirections may replace)."""

    @property  # type: ignore[override]
    def stream(self) -> Any:
        return sys.stderr

    @stream.setter
    def stream(self, _value: Any) -> None:
        pass


def _own_words_only(command: str) -> None:
    """viewcomp's log lines on stderr as ``viewcomp COMMAND: ...`` (WARNING and up unless a
    command lowers the ``viewcomp`` logger's level); other libraries' log output is not
    shown: OpenCV's (its own logger, silenced) and python-osc's (the root logger, which gets
    a handler that drops everything). viewcomp reports what went wrong in its own words."""
    os.environ.setdefault("OPENCV_LOG_LEVEL", "SILENT")
    if "cv2" in sys.modules:  # imported already: its logger was set up from the environment
        cv2 = sys.modules["cv2"]
        cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)
    root = logging.getLogger()
    if not any(isinstance(h, logging.NullHandler) for h in root.handlers):
        root.addHandler(logging.NullHandler())
    own = logging.getLogger("viewcomp")
    for h in [h for h in own.handlers if isinstance(h, _StderrHandler)]:
        own.removeHandler(h)
    handler = _StderrHandler()
    handler.setFormatter(logging.Formatter(f"viewcomp {command}: %(message)s"))
    own.addHandler(handler)
    own.setLevel(logging.WARNING)


class Terminated(KeyboardInterrupt):
    """SIGTERM (a service manager, ``kill``): raised in the main thread, so that what a
    command was writing is cleaned up as for Ctrl-C (the atomic writers remove their partial
    files on any exception)."""


def _on_sigterm(signum: int, frame: object) -> None:
    raise Terminated


_DASH_VALUE = re.compile(r"^-[0-9.]")


def _value_options(parser: argparse.ArgumentParser) -> set[str]:
    """The option strings, in every sub-command, that take exactly one value."""
    found: set[str] = set()
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                found |= _value_options(sub)
        elif isinstance(action, argparse._StoreAction | argparse._AppendAction) and (
            action.nargs is None and action.option_strings
        ):
            found.update(action.option_strings)
    return found


def join_dash_values(parser: argparse.ArgumentParser, argv: Sequence[str]) -> list[str]:
    """``argv`` with each value that begins with '-' and a digit or '.' joined to the option
    before it (``--eye -0.2,0,1`` -> ``--eye=-0.2,0,1``; ``-o -5.png`` -> ``-o-5.png``) when
    that option takes one value.

    argparse takes such a token for an option unless it is a plain negative number, and
    answers "expected one argument": a viewer left of the screen's centre (x < 0) could not
    be given, and a mistyped ``--size -5x10`` got that message instead of the size's own.
    """
    takes = _value_options(parser)
    out: list[str] = []
    i = 0
    while i < len(argv):
        token = argv[i]
        if token == "--":
            out += argv[i:]
            break
        if token in takes and i + 1 < len(argv) and _DASH_VALUE.match(argv[i + 1]):
            sep = "=" if token.startswith("--") else ""
            out.append(f"{token}{sep}{argv[i + 1]}")
            i += 2
            continue
        out.append(token)
        i += 1
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status.

    0: done. 2: a refusal (a :class:`ViewcompError`, an operating-system error such as a
    full disk, or a bad option): one line naming the thing at fault and the fix, nothing
    written; a bad option (argparse's or a :class:`UsageError`) raises ``SystemExit(2)``
    as argparse does. 1: any other exception, which is a bug: its traceback and a note asking to
    report it. 130: interrupted (Ctrl-C), 143: terminated (SIGTERM); partial outputs are
    removed as for an error.
    """
    os.environ.setdefault("OPENCV_LOG_LEVEL", "SILENT")  # before anything imports cv2
    parser = build_parser()
    args = parser.parse_args(join_dash_values(parser, sys.argv[1:] if argv is None else argv))
    _own_words_only(args.command)
    name = f"viewcomp {args.command}"
    previous = None
    if threading.current_thread() is threading.main_thread():
        if signal.getsignal(signal.SIGTERM) == signal.SIG_DFL:  # a host's handler stays
            previous = signal.signal(signal.SIGTERM, _on_sigterm)
    try:
        return _run(args, parser, name)
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


def _run(args: argparse.Namespace, parser: argparse.ArgumentParser, name: str) -> int:
    """``args.run(args)`` with :func:`main`'s exit statuses and messages."""
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
    except Terminated:
        print(f"{name}: terminated", file=sys.stderr)
        return 143
    except KeyboardInterrupt:
        print(f"{name}: interrupted", file=sys.stderr)
        return 130
    except Exception:
        traceback.print_exc()
        print(f"{name}: internal error: {BUG_NOTE}", file=sys.stderr)
        return 1
