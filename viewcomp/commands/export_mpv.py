"""`viewcomp export-mpv CALIB -o compensate.glsl`: the compensation as an mpv user shader."""

from __future__ import annotations

import argparse
import shlex
from pathlib import Path

from viewcomp.commands._common import (
    add_eye_arguments,
    add_tone_arguments,
    add_tone_choice,
    finite,
    parse_vec3,
    positive,
)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "export-mpv",
        help="write the compensation as an mpv user shader (for kiosks that run mpv)",
        description="Write an mpv user shader (//!HOOK OUTPUT, maps and LUTs embedded as "
        "//!TEXTURE) that compensates everything mpv shows for one calibration. The angle "
        "is fixed at export (works with vo=gpu and vo=gpu-next), or with --param a "
        "//!PARAM angle set by --glsl-shader-opts=angle=DEG (vo=gpu-next with a libplacebo "
        "that supports it; see docs/PLAYER.md). The tone map is baked too: from "
        "--tone-from (a typical frame), or a conservative one that keeps any content in "
        "range. It prints the mpv command line to play with (its --vf fits the video to the "
        "calibration grid as `viewcomp render` does; with --guard, mpv stops when it "
        "rejects the shader). `viewcomp check-mpv FILE` checks the installed mpv runs it.",
    )
    p.add_argument("calib", help="calibration bundle from `viewcomp calibrate`")
    p.add_argument("-o", "--output", required=True, help="the shader file to write (.glsl)")
    add_eye_arguments(
        p, angle_note="; default 90, with --param the parameter's default", audience=True
    )
    p.add_argument(
        "--param", action="store_true", help="make the angle a //!PARAM (pixel method, vo=gpu-next)"
    )
    add_tone_arguments(p, smooth=False)
    p.add_argument(
        "--tone-from", metavar="IMAGE", help="choose the tone map for this image (a typical frame)"
    )
    add_tone_choice(p, "; adaptive: one field per export, for --tone-from, a fixed eye")
    p.add_argument("--alpha", type=positive, default=None, help="bake this tone-map alpha (> 0)")
    p.add_argument("--beta", type=finite, default=None, help="bake this tone-map beta")
    p.add_argument(
        "--precision",
        type=int,
        choices=[8, 16, 32],
        default=16,
        help="bits per embedded map value (16: rgba16; 32: rgba32f, exact, twice "
        "the size; 8: a smooth base plus an 8-bit residual, about half the size, "
        "fixed angle, pixel method)",
    )
    p.add_argument(
        "--guard",
        metavar="FILE.lua",
        help="also write an mpv script that stops mpv (exit status 2) when it "
        "rejects the shader, instead of playing uncompensated video; the printed "
        "command line loads it with --script",
    )
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from viewcomp.calib.comp.tonemap import DEFAULT_LAMBDA
    from viewcomp.calib.errors import OutputError, UsageError, describe_os_error
    from viewcomp.calib.fit.calibrate import Calibration
    from viewcomp.calib.io.atomic import write_text_atomic
    from viewcomp.calib.io.imageio import read_rgb8
    from viewcomp.rt.export.mpv import export_mpv_shader, guard_script, mpv_args
    from viewcomp.rt.media.frames import fit_rgb

    if (args.alpha is None) != (args.beta is None):
        raise UsageError("give both --alpha and --beta, or neither")
    if args.tone_from and args.alpha is not None:
        raise UsageError("--tone-from and --alpha/--beta both set the tone map; give one")
    _check_args(args)
    cal = Calibration.load(args.calib)
    audience = None
    if args.audience is not None:
        from viewcomp.calib.world.audience import parse_audience

        v = cal.rig.viewer
        audience = parse_audience(args.audience, v.distance, v.height or 0.0)
    sample = None
    if args.tone_from:  # fitted to the grid as render fits it
        h, w = cal.shape
        sample = fit_rgb(read_rgb8(args.tone_from), w, h)
    text, info = export_mpv_shader(
        cal,
        method=args.method,
        angle=args.angle if args.angle is not None or args.eye else 90.0,
        eye=parse_vec3(args.eye) if args.eye else None,
        audience=audience,
        param=args.param,
        lam=DEFAULT_LAMBDA if args.lam is None else args.lam,
        tone_sample=sample,
        tone=None if args.alpha is None else (args.alpha, args.beta),
        precision=args.precision,
        source=Path(args.calib).name,
        tone_mode=args.tone,
    )
    if args.guard and Path(args.guard).resolve() in (
        Path(args.output).resolve(),
        Path(args.calib).resolve(),
    ):
        raise UsageError("--guard names the shader or the calibration; give its own file")
    try:
        write_text_atomic(args.output, text, encoding="ascii")
        if args.guard:
            write_text_atomic(args.guard, guard_script(), encoding="utf-8")
    except OSError as exc:
        raise OutputError(f"cannot write {describe_os_error(exc, args.output)}") from None
    w, h = info.grid
    where = (
        "angle as //!PARAM"
        if info.param
        else (f"angle {info.angle:g} deg" if info.angle is not None else "fixed eye")
    )
    if audience is not None and len(audience) > 1:
        where = f"an audience of {len(audience)} viewers"
    print(
        f"wrote {args.output}: {info.bytes / 1e6:.1f} MB, {info.method} method, {where}, "
        f"grid {w}x{h}, alpha {info.alpha:.3f} beta {info.beta:.4f}"
    )
    print(
        "play fullscreen on the projector with: mpv "
        + " ".join(shlex.quote(a) for a in mpv_args(args.output, info.grid, args.guard))
        + " --fullscreen VIDEO"
    )
    return 0


def _check_args(args: argparse.Namespace) -> None:
    """Before any work: the eye within the limits, the shader file never the bundle or the
    tone image."""
    from viewcomp.calib.world.eye import check_angle, check_eye
    from viewcomp.commands._common import check_output_file

    if args.angle is not None:
        check_angle(args.angle, "--angle")
    if args.eye:
        check_eye(parse_vec3(args.eye), f"--eye {args.eye}")
    if args.audience is not None:  # the grammar before any work (angles use the rig's viewer)
        from viewcomp.calib.world.audience import parse_audience

        parse_audience(args.audience, 1.0, 0.0)
    check_output_file(args.output, args.calib, args.tone_from)
