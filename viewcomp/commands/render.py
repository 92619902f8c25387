"""`viewcomp render CALIB INPUT -o OUTPUT`: compensate an image or a video headlessly."""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from viewcomp.commands._common import (
    add_eye_arguments,
    add_tone_arguments,
    add_tone_choice,
    check_tone,
    finite,
    parse_vec3,
)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "render",
        help="compensate an image or a video for a viewing angle (headless)",
        description="Compensate an image (PNG, JPEG or TIFF out) or a video (H.264, H.265, "
        "ProRes, DNxHR, HAP, VP9, AV1 or FFV1 out, audio carried over; or an image sequence) "
        "so that, projected on the calibrated screen, it looks as on a white screen "
        "to a viewer at the given angle or eye position. An input of another size is scaled "
        "to fit the projector, aspect kept, centred on black. The tone map (alpha, beta of "
        "Eq. 21) comes per frame from a small thumbnail and, for video, is smoothed over "
        "time (--smooth) so brightness does not flicker.",
    )
    p.add_argument("calib", help="calibration bundle from `viewcomp calibrate`")
    p.add_argument("input", help="image (.png, .jpg, ...) or video (anything FFmpeg reads)")
    p.add_argument(
        "-o",
        "--output",
        required=True,
        help=".png/.jpg/.tif for an image; for a video .mp4/.mov/.mkv/.webm, or DIR/%%05d.png "
        "(.jpg, .tif) for one image per frame",
    )
    add_eye_arguments(p, required=True, track=True, audience=True)
    add_tone_arguments(p)
    add_tone_choice(p)
    p.add_argument(
        "--backend",
        choices=["gl", "cpu"],
        default="gl",
        help="gl: the GLSL shader (default); cpu: the numpy reference",
    )
    p.add_argument(
        "--identity",
        action="store_true",
        help="run the same pipeline with compensation off (A/B, timing)",
    )
    p.add_argument(
        "--crf",
        type=finite,
        default=18,
        help="video quality (CRF of x264/x265/VP9/AV1, default 18)",
    )
    p.add_argument(
        "--codec",
        default=None,
        help="video codec: libx264 (h264), libx265 (hevc), prores_ks (prores), "
        "dnxhd (dnxhr), hap, libvpx-vp9 (vp9), libsvtav1 (av1), ffv1 (default: "
        "libx264, libvpx-vp9 for .webm)",
    )
    p.add_argument(
        "--profile",
        default=None,
        help="codec profile: ProRes hq (422 HQ, default), standard, lt, proxy, "
        "4444; DNxHR hq (default), sq, lb, hqx; HAP hap (default), hap_q",
    )
    p.add_argument("--preset", default=None, help="encoder preset, e.g. veryfast (x264)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from viewcomp.calib.comp.compensation import Compensation
    from viewcomp.calib.comp.tonemap import DEFAULT_LAMBDA
    from viewcomp.calib.errors import UsageError
    from viewcomp.calib.fit.calibrate import Calibration
    from viewcomp.calib.world.audience import parse_audience
    from viewcomp.rt.media.formats import is_sequence_pattern
    from viewcomp.rt.render.pipeline import is_image, render_file
    from viewcomp.rt.render.tracks import constant_audience, constant_eye, load_angle_track

    _check_args(args)  # the output's format too: before the calibration or input is read
    cal = Calibration.load(args.calib)
    v = cal.rig.viewer
    if args.track is not None:
        track = load_angle_track(args.track, v.distance, v.height)
    elif args.audience is not None:
        audience = parse_audience(args.audience, v.distance, v.height)
        if len(audience) > 1 and args.method != "pixel":
            raise UsageError("--audience with several viewers needs --method pixel")
        track = constant_audience(audience)
    else:
        eye = cal.eye(args.angle, parse_vec3(args.eye) if args.eye else None)
        track = constant_eye(*eye)
    lam = DEFAULT_LAMBDA if args.lam is None else args.lam
    tau = None if is_image(Path(args.input)) else args.smooth
    comp = Compensation(cal, args.method, lam, tau=tau, tone=args.tone)
    kwargs = {"preset": args.preset} if args.preset else {}
    stats = render_file(
        comp,
        args.input,
        args.output,
        track,
        backend=args.backend,
        identity=args.identity,
        crf=args.crf,
        codec=args.codec,
        profile=args.profile,
        progress=not args.quiet,
        **kwargs,
    )
    what = "identity (compensation off)" if args.identity else f"{args.method} method"
    if is_image(Path(args.input)):  # one picture: a frame rate would mean nothing
        done = f"an image, {what}, {args.backend} backend, in {stats.seconds:.1f} s"
    elif is_sequence_pattern(args.output):
        folder = Path(args.output).parent
        print(
            f"wrote {stats.frames} images to {folder}{os.sep} ({Path(args.output).name}, "
            f"numbered from 0; no audio): {what}, {stats.fps:.1f} frames/s"
        )
        return 0
    else:
        done = f"{stats.frames} frames, {what}, {args.backend} backend, {stats.fps:.1f} frames/s"
    print(f"wrote {args.output}: {done}")
    return 0


def _check_args(args: argparse.Namespace) -> None:
    """Before any work: the input usable, the eye within the limits, the output never an
    input, its extension, codec and profile working together (the grid's size is checked
    once the calibration is loaded, still before the input is decoded)."""
    from viewcomp.calib.io.paths import check_input_file
    from viewcomp.calib.world.eye import check_angle, check_eye
    from viewcomp.commands._common import check_output_file, check_output_folder
    from viewcomp.rt.media.formats import is_sequence_pattern, plan_output
    from viewcomp.rt.render.pipeline import is_image

    check_input_file(args.input, "input", "an image or a video file")
    check_tone(args)
    if args.angle is not None:
        check_angle(args.angle, "--angle")
    if args.eye:
        check_eye(parse_vec3(args.eye), f"--eye {args.eye}")
    if args.audience is not None:  # the grammar before any work (angles use the rig's viewer)
        from viewcomp.calib.world.audience import parse_audience

        parse_audience(args.audience, 1.0, 0.0)
    if is_sequence_pattern(args.output) and not is_image(args.input):
        folder = str(Path(args.output).parent)
        check_output_folder(folder, args.calib, args.input, args.track, what="image sequence")
    else:
        check_output_file(args.output, args.calib, args.input, args.track)
    plan_output(args.output, is_image(args.input), args.codec, args.profile)
