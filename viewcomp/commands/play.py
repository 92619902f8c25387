"""`viewcomp play CALIB VIDEO...`: fullscreen playback with a live viewing angle."""

from __future__ import annotations

import argparse
import logging
import sys

from viewcomp.commands._common import (
    add_eye_arguments,
    add_tone_arguments,
    add_tone_choice,
    check_tone,
    nonnegative,
    parse_size,
    parse_vec3,
)
from viewcomp.commands.track import add_tracking_camera_arguments, checked_ipd

EPILOG = """\
live angle input and show control:
  keys      Left/Right turn by --step degrees (Shift: 5x), Home: back to the start angle,
            Space: pause/resume, ]/[: seek 10 s on/back, N or Page Down: next file,
            P or Page Up: previous file, B: blackout on/off, S: status to stdout,
            O: overlay (angle, eye, fps, drops), C: compensation on/off, Esc/Q: quit
  mouse     drag with the left button: the window's width is 180 degrees
  OSC/UDP   to --osc HOST:PORT: /viewcomp/angle f (degrees), /viewcomp/angle/norm f (0..1
            onto --norm-angle-range), /viewcomp/eye f f f (metres), /viewcomp/eyes f f f ...
            (an audience), /viewcomp/pause, /viewcomp/resume, /viewcomp/seek f (seconds),
            /viewcomp/next, /viewcomp/previous,
            /viewcomp/blackout i (1 black, 0 picture), /viewcomp/status (answered to the
            sender: file, position s, paused, angle, eye x y z, fps, dropped, blackout)
  stdin     lines `angle 60`, `norm 0.5`, `eye 0.1 0.0 0.5`, `eyes X1 Y1 Z1 X2 ...`,
            `pause`, `resume`, `seek 12.5`, `next`, `previous`, `blackout 1`, `status`
            (printed to stdout)
  camera    --track-camera SRC: every face's eye, an audience (--track-faces nearest: one)
Moves are smoothed (--eye-smooth); malformed messages are logged and dropped.
"""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "play",
        help="fullscreen playback with a live viewing angle (OSC, stdin, keys, mouse)",
        description="Play videos through the compensation, fullscreen on the projector, at "
        "their frame rate (late frames are dropped, never delayed), with the viewing angle "
        "changing live. Several files or a folder make a playlist; --loop repeats it.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("calib", nargs="?", help="calibration bundle from `viewcomp calibrate`")
    p.add_argument("videos", nargs="*", metavar="VIDEO", help="video files or folders")
    add_eye_arguments(p, angle_default=90.0, angle_note="; where playback starts", audience=True)
    p.add_argument("--monitor", type=int, default=0, help="monitor index (see --list-monitors)")
    p.add_argument("--list-monitors", action="store_true", help="list the monitors and exit")
    p.add_argument("--windowed", action="store_true", help="a window instead of fullscreen")
    p.add_argument("--size", help="window size WxH (windowed: default the calibration grid)")
    p.add_argument("--no-vsync", action="store_true", help="do not wait for the display refresh")
    p.add_argument("--loop", action="store_true", help="repeat the playlist until stopped")
    p.add_argument(
        "--osc", metavar="HOST:PORT", help="listen for OSC on UDP HOST:PORT (e.g. 127.0.0.1:9000)"
    )
    p.add_argument("--no-stdin", action="store_true", help="do not read commands from stdin")
    p.add_argument(
        "--track-camera",
        metavar="SRC",
        help="follow the faces in camera SRC (see `viewcomp track`)",
    )
    p.add_argument(
        "--track-faces",
        choices=["all", "nearest"],
        default="all",
        help="with --track-camera: compensate for every face seen at once (all, "
        "the default; pixel method) or for the nearest one",
    )
    add_tracking_camera_arguments(p.add_argument_group("tracking camera (--track-camera)"))
    add_tone_arguments(p)
    add_tone_choice(p, "; chosen per shot on the tone worker")
    p.add_argument(
        "--eye-smooth",
        type=float,
        default=0.25,
        help="eye smoothing time constant, s (default 0.25; 0: instant)",
    )
    p.add_argument("--step", type=float, default=2.0, help="degrees per arrow key (default 2)")
    p.add_argument("--overlay", action="store_true", help="start with the overlay shown")
    p.add_argument("--no-audio", action="store_true", help="play silently")
    p.add_argument("--audio-device", default="default", help="ALSA PCM name (default: default)")
    p.add_argument(
        "--scale",
        choices=["auto", "linear", "nearest"],
        default="auto",
        help="filter when the window is not the grid's size (default auto: "
        "nearest for whole-number factors, else linear)",
    )
    p.add_argument("--seconds", type=float, default=None, help="stop after this many seconds")
    p.add_argument("--quiet", action="store_true", help="no log lines, only the summary")
    _add_show_control(p)
    p.set_defaults(run=run)


def _add_show_control(p: argparse.ArgumentParser) -> None:
    """The options of the show-control group."""
    show = p.add_argument_group("show control")
    show.add_argument(
        "--still-seconds",
        type=nonnegative,
        default=10.0,
        metavar="S",
        help="how long an image file of the playlist stays up (default 10)",
    )
    show.add_argument(
        "--norm-angle-range",
        default="30:150",
        metavar="LO:HI",
        help="angles (degrees) that /viewcomp/angle/norm 0 and 1 mean (default 30:150)",
    )
    show.add_argument(
        "--osc-feedback",
        metavar="HOST:PORT",
        help="push /viewcomp/status to HOST:PORT every --feedback-every s",
    )
    show.add_argument(
        "--feedback-every",
        type=nonnegative,
        default=1.0,
        metavar="S",
        help="seconds between status pushes (default 1)",
    )


def _stdin_fd() -> int | None:
    """Standard input's descriptor, or None when there is none (closed, not a file)."""
    try:
        return sys.stdin.fileno()
    except (AttributeError, OSError, ValueError):
        return None


def _tracker(args: argparse.Namespace, rig: object, all_faces: bool) -> tuple[object, ...]:
    """The face tracker of ``--track-camera`` (opened now, so a bad SRC fails early): the
    bundle's tracking camera or ``--tracker``'s, ``--detector``, ``--ipd`` and
    ``--no-face-height`` and ``--no-mirror`` as for ``viewcomp track``, its other options at
    their defaults."""
    from viewcomp.calib.errors import UsageError

    if not args.track_camera:
        if args.tracker:
            raise UsageError(
                f"--tracker {args.tracker} describes the camera of --track-camera; give "
                "--track-camera SRC too"
            )
        return ()
    from dataclasses import replace

    from viewcomp.calib.world.tracker import with_tracker_file
    from viewcomp.rt.track.run import TrackerThread, build, default_options

    rig = with_tracker_file(rig, args.tracker)  # type: ignore[arg-type]
    options = default_options(rig)
    options = replace(
        options,
        tracker=replace(options.tracker, face_height=not args.no_face_height),
        yunet=replace(options.yunet, mirror=not args.no_mirror),
        detector_kind=args.detector,
        ipd=checked_ipd(args, rig),
        realtime=True,  # a video or an image sequence is paced as a camera would be
    )
    pipeline = build(args.track_camera, rig, options)
    return (TrackerThread(pipeline, all_faces),)


def _norm_range(text: str) -> tuple[float, float]:
    """``--norm-angle-range LO:HI`` (degrees) as checked by ``check_norm_range``."""
    from viewcomp.rt.play.live import InputError, check_norm_range

    lo, sep, hi = text.partition(":")
    try:
        bounds = (float(lo), float(hi)) if sep else None
    except ValueError:
        bounds = None
    if bounds is None:
        raise InputError(f"--norm-angle-range is LO:HI in degrees, e.g. 30:150; got {text!r}")
    return check_norm_range(*bounds)


def run(args: argparse.Namespace) -> int:
    from viewcomp.calib.errors import UsageError
    from viewcomp.rt.play.live import (
        InputError,
        check_angle,
        check_eye,
        parse_host_port,
    )
    from viewcomp.rt.play.player import Player, PlayerError, PlayerOptions, list_monitors

    logging.getLogger("viewcomp").setLevel(logging.WARNING if args.quiet else logging.INFO)
    try:
        if args.list_monitors:
            for m in list_monitors():
                print(m)
            return 0
        if not args.calib or not args.videos:
            raise UsageError("give a calibration bundle and at least one video (or a folder)")
        check_tone(args)
        osc = parse_host_port(args.osc) if args.osc else None
        eye = check_eye(tuple(parse_vec3(args.eye))) if args.eye else None
        angle = check_angle(args.angle)
        feedback = parse_host_port(args.osc_feedback) if args.osc_feedback else None
        norm_range = _norm_range(args.norm_angle_range)
        if args.feedback_every <= 0:
            raise InputError("--feedback-every is a number of seconds > 0, e.g. 1")
        from viewcomp.calib.comp.tonemap import DEFAULT_LAMBDA
        from viewcomp.calib.fit.calibrate import Calibration

        cal = Calibration.load(args.calib)
        audience = None
        if args.audience is not None:
            from viewcomp.calib.world.audience import parse_audience

            v = cal.rig.viewer
            audience = parse_audience(args.audience, v.distance, v.height or 0.0)
            if len(audience) > 1 and args.method != "pixel":
                raise UsageError("--audience with several viewers needs --method pixel")
        options = PlayerOptions(
            method=args.method,
            lam=DEFAULT_LAMBDA if args.lam is None else args.lam,
            tone=args.tone,
            tone_tau=args.smooth,
            eye_tau=args.eye_smooth,
            angle=angle,
            eye=eye,
            angle_step=args.step,
            monitor=args.monitor,
            windowed=args.windowed,
            size=parse_size(args.size) if args.size else None,
            vsync=not args.no_vsync,
            loop=args.loop,
            osc=osc,
            stdin_fd=None if args.no_stdin else _stdin_fd(),
            audio=not args.no_audio,
            audio_device=args.audio_device,
            overlay=args.overlay,
            scale=args.scale,
            max_seconds=args.seconds,
            still_seconds=args.still_seconds,
            norm_range=norm_range,
            osc_feedback=feedback,
            feedback_every=args.feedback_every,
            audience=audience,
            inputs=_tracker(args, cal.rig, args.track_faces == "all" and args.method == "pixel"),
        )
        stats = Player(cal, args.videos, options).run()
    except PlayerError as exc:
        print(f"viewcomp play: error: {exc}", file=sys.stderr)
        return 2
    print(stats.summary())
    return 0
