"""The `viewcomp` command line: one sub-command per module in ``viewcomp.commands``."""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

from viewcomp import __version__

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
    "track",
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
  viewcomp track --camera 0 --rig screen.vcb | viewcomp play ...  follow the viewer's face
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


def _known_errors() -> tuple[type[BaseException], ...]:
    """Errors that carry a message for the user (cause and fix): no traceback for these."""
    from viewcomp.calib.errors import FitError
    from viewcomp.calib.io.bundle import BundleError
    from viewcomp.calib.io.imageio import CaptureError
    from viewcomp.calib.sim.simulator import SimulatorError
    from viewcomp.calib.world.geometry import GeometryError
    from viewcomp.calib.world.rig import RigError

    errors: list[type[BaseException]] = [
        BundleError, FitError, GeometryError, CaptureError, RigError, SimulatorError,
    ]  # fmt: skip
    try:
        from viewcomp.rt.gl.context import GLUnavailable
        from viewcomp.rt.media.video import VideoError
        from viewcomp.rt.render.pipeline import ImageError
        from viewcomp.rt.render.tracks import TrackError
        from viewcomp.rt.track.source import SourceError

        errors += [GLUnavailable, ImageError, TrackError, VideoError, SourceError]
    except ImportError:  # the run-time part is optional for calibration-only installs
        pass
    return tuple(errors)


class UsageError(Exception):
    """A command-line value that is wrong: the message says which and what is expected."""


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status (0 ok, 2 a user error)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.run(args) or 0)
    except UsageError as e:
        parser.exit(2, f"viewcomp {args.command}: error: {e}\n")
    except _known_errors() as e:
        print(f"viewcomp {args.command}: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"viewcomp {args.command}: interrupted", file=sys.stderr)
        return 130
    return 0
