"""`viewcomp track --camera SRC --rig RIG`: follow viewers' faces, publish their eyes live."""

from __future__ import annotations

import argparse
import sys

from viewcomp.commands._common import nonnegative, parse_vec3

EPILOG = """\
output (metres, world frame: screen plane z = 0, +y up, +z toward the audience):
  --faces nearest   lines `eye X Y Z` on stdout, OSC /viewcomp/eye f f f
  --faces all       lines `eyes X1 Y1 Z1 X2 Y2 Z2 ...`, OSC /viewcomp/eyes with 3k floats
A line is written only when the eye changed. Typical use:
  viewcomp track --camera 0 --rig screen.vcb | viewcomp play screen.vcb clip.mp4
"""


def positive(text: str) -> float:
    """An argparse type: a finite number > 0."""
    v = nonnegative(text)
    if v <= 0:
        raise argparse.ArgumentTypeError(f"expected a number > 0, got {text!r}")
    return v


def add_tracking_camera_arguments(g: argparse._ArgumentGroup) -> None:
    """The options ``track`` shares with ``play --track-camera``: the tracking camera, the
    face model and the interpupillary distance."""
    g.add_argument(
        "--tracker",
        metavar="FILE.toml",
        help="the tracking camera from the [tracker] table of FILE.toml instead of the "
        "rig's (add or move a webcam without recalibrating)",
    )
    g.add_argument(
        "--detector",
        choices=["yunet", "cascade"],
        default="yunet",
        help="yunet (default): distance from the eyes' separation; cascade: the "
        "old LBP fallback, distance from the box size (biased)",
    )
    g.add_argument(
        "--ipd",
        type=positive,
        default=None,
        metavar="M",
        help="viewers' interpupillary distance, metres (default: the rig's "
        "[tracker] ipd, else 0.063)",
    )
    g.add_argument(
        "--no-face-height",
        action="store_true",
        help="range every face by its eyes' separation alone (default: each viewer's face "
        "height, eyes to mouth, learned while they face the screen, ranges their turned head)",
    )
    g.add_argument(
        "--no-mirror",
        action="store_true",
        help="--detector yunet: read a small face's enlarged crop once (default: also "
        "mirrored, the two readings averaged: YuNet's landmarks lean to one side, by up to "
        "a few %% of the distance; the mirror costs a second crop, about 10 ms a face a frame "
        "on one core). A face scored under 0.8 is still read mirrored, to check that it is one",
    )


def add_tracker_arguments(p: argparse.ArgumentParser) -> None:
    """The tracking options: camera and face model (shared with ``play --track-camera``),
    timing, filter."""
    g = p.add_argument_group("tracking")
    add_tracking_camera_arguments(g)
    g.add_argument(
        "--face-width",
        type=positive,
        default=0.15,
        metavar="M",
        help="--detector cascade only: width of a face's box, metres (default 0.15)",
    )
    g.add_argument(
        "--hold",
        type=nonnegative,
        default=1.0,
        metavar="S",
        help="seconds a lost face's eye is held (default 1)",
    )
    g.add_argument(
        "--ease",
        type=nonnegative,
        default=1.0,
        metavar="S",
        help="seconds to ease from a lost eye to the default (default 1)",
    )
    g.add_argument(
        "--default-angle",
        type=float,
        default=90.0,
        metavar="DEG",
        help="the eye when nobody is seen: this viewing angle at the rig's [viewer] "
        "distance and height (default 90)",
    )
    g.add_argument("--default-eye", metavar="X,Y,Z", help="the eye when nobody is seen, metres")
    g.add_argument(
        "--min-cutoff",
        type=positive,
        default=2.0,
        metavar="HZ",
        help="One-Euro filter cutoff at rest, Hz (default 2)",
    )
    g.add_argument(
        "--beta",
        type=nonnegative,
        default=5.0,
        help="One-Euro filter speed coefficient, Hz per m/s (default 5)",
    )
    g.add_argument(
        "--near",
        type=positive,
        default=0.5,
        metavar="M",
        help="nearest face searched, metres from the camera (default 0.5)",
    )
    g.add_argument(
        "--far",
        type=positive,
        default=4.0,
        metavar="M",
        help="farthest face searched, metres (default 4)",
    )
    g.add_argument(
        "--fps", type=positive, default=30.0, help="frame rate of an image sequence (default 30)"
    )


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "track",
        help="follow viewers with a camera; publish their eye positions (stdout, OSC)",
        description="Detect faces in a camera's frames, estimate each viewer's eye position "
        "from its eye landmarks (their separation at an adult interpupillary distance, "
        "corrected for head turn) and the tracking camera of the rig ([tracker], or "
        "[camera] without one), smooth it (One-Euro filter) and publish it live.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument(
        "--camera",
        required=True,
        metavar="SRC",
        help="camera index (0, 1, ...), a video file, a folder of images or a "
        "glob ('frames/*.png')",
    )
    p.add_argument(
        "--rig",
        required=True,
        metavar="FILE",
        help="the tracking camera's pose and intrinsics: a rig.toml, a capture "
        "set folder or a calibration bundle",
    )
    p.add_argument(
        "--faces",
        choices=["nearest", "all"],
        default="nearest",
        help="publish the nearest viewer (default) or all of them",
    )
    p.add_argument(
        "--osc", metavar="HOST:PORT", help="also send OSC to HOST:PORT (e.g. 127.0.0.1:9000)"
    )
    p.add_argument("--no-stdout", action="store_true", help="write no lines on stdout")
    p.add_argument(
        "--realtime",
        action="store_true",
        help="pace a video file or image sequence at its frame rate",
    )
    p.add_argument(
        "--seconds", type=positive, default=None, help="stop after this many seconds of frames"
    )
    p.add_argument("--quiet", action="store_true", help="no summary on stderr")
    add_tracker_arguments(p)
    p.set_defaults(run=run)


def checked_ipd(args: argparse.Namespace, rig: object) -> float:
    """``--ipd`` (checked: 0.04..0.09 m), else the rig's ``[tracker] ipd``, else 0.063."""
    from viewcomp.calib.errors import UsageError
    from viewcomp.rt.track.anatomy import IPD

    ipd = args.ipd
    if ipd is None:
        return float(getattr(rig, "tracker_ipd", None) or IPD)
    if not 0.04 <= ipd <= 0.09:
        raise UsageError(
            f"--ipd {ipd:g}: the interpupillary distance is in metres, 0.04..0.09 "
            "(adults about 0.063)"
        )
    return float(ipd)


def tracking_rig(args: argparse.Namespace) -> object:
    """The rig of ``--rig`` with the tracking camera of ``--tracker`` when given.

    Raises:
        RigError, BundleError: a file cannot be read; the message names it and the fix.
    """
    from viewcomp.calib.world.tracker import with_tracker_file
    from viewcomp.rt.track.run import load_tracking_rig

    return with_tracker_file(load_tracking_rig(args.rig), args.tracker)


def tracker_options(args: argparse.Namespace, rig: object) -> object:
    """The :class:`viewcomp.rt.track.run.TrackOptions` for parsed arguments and a rig."""
    from viewcomp.calib.errors import UsageError
    from viewcomp.rt.play.live import InputError, check_angle, check_eye
    from viewcomp.rt.track.run import TrackOptions
    from viewcomp.rt.track.tracker import TrackerConfig
    from viewcomp.rt.track.yunet import YuNetConfig

    try:
        if args.default_eye:
            default = check_eye(tuple(parse_vec3(args.default_eye, "--default-eye")))
        else:
            e = rig.viewer.eye(check_angle(args.default_angle))  # type: ignore[attr-defined]
            default = (float(e[0]), float(e[1]), float(e[2]))
    except InputError as exc:
        raise UsageError(f"the default eye: {exc}") from None
    if args.near >= args.far:
        raise UsageError(f"--near ({args.near:g} m) must be less than --far ({args.far:g} m)")
    config = TrackerConfig(
        faces=getattr(args, "faces", "nearest"),
        default_eye=default,
        hold=args.hold,
        ease=args.ease,
        min_cutoff=args.min_cutoff,
        beta=args.beta,
        face_height=not args.no_face_height,
    )
    return TrackOptions(
        detector_kind=args.detector,
        ipd=checked_ipd(args, rig),
        face_width=args.face_width,
        near=args.near,
        far=args.far,
        fps=args.fps,
        realtime=getattr(args, "realtime", False),
        tracker=config,
        yunet=YuNetConfig(mirror=not args.no_mirror),
    )


def run(args: argparse.Namespace) -> int:
    from viewcomp.calib.errors import UsageError
    from viewcomp.rt.play.live import InputError, parse_host_port
    from viewcomp.rt.track.publish import LinePublisher, OscPublisher, Publisher
    from viewcomp.rt.track.run import build
    from viewcomp.rt.track.source import SourceError

    rig = tracking_rig(args)
    options = tracker_options(args, rig)
    all_faces = args.faces == "all"
    publishers: list[Publisher] = []
    if not args.no_stdout:
        publishers.append(LinePublisher(sys.stdout, all_faces))
    if args.osc:
        try:
            host, port = parse_host_port(args.osc)
            publishers.append(OscPublisher(host, port, all_faces))
        except (InputError, OSError) as exc:
            raise UsageError(f"--osc {args.osc}: {exc}") from None
    try:
        pipeline = build(args.camera, rig, options, publishers)  # type: ignore[arg-type]
    except SourceError as exc:
        print(f"viewcomp track: error: --camera {exc}", file=sys.stderr)
        return 2
    try:
        stats = pipeline.run(max_seconds=args.seconds)
    except BrokenPipeError:  # the reader (e.g. the player) has gone: a normal end
        sys.stderr.close()
        return 0
    except SourceError as exc:
        print(f"viewcomp track: error: --camera {exc}", file=sys.stderr)
        return 2
    finally:
        pipeline.close()
    if not args.quiet:
        print(f"viewcomp track: {stats.summary()}", file=sys.stderr)
    return 0
