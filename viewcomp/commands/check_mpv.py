"""`viewcomp check-mpv SHADER`: does the installed mpv run this exported shader?"""

from __future__ import annotations

import argparse
import sys


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "check-mpv",
        help="check that the installed mpv runs an exported shader (exit 2 if it rejects it)",
        description="Run the installed mpv for one frame of a tiny still through SHADER "
        "(with export-mpv's guard script; on this display, or a private Xvfb with --headless "
        "or without one) and say "
        "whether mpv ran it. mpv skips a shader it cannot parse or compile and plays "
        "uncompensated with exit status 0; this exits with status 2 and mpv's error instead. "
        "A video output that cannot open (no display, no GPU context) is said as such: the "
        "shader was then not tried.",
    )
    p.add_argument("shader", help="the shader file from `viewcomp export-mpv`")
    p.add_argument(
        "--vo",
        choices=["gpu", "gpu-next"],
        default="gpu",
        help="mpv's video output to check with (default gpu)",
    )
    p.add_argument(
        "--headless",
        action="store_true",
        help="check on a private Xvfb with software OpenGL even when there is a "
        "display (the default without one)",
    )
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from viewcomp.rt.export.mpv_check import MpvCheckError, check_mpv

    try:
        result = check_mpv(args.shader, vo=args.vo, headless=args.headless)
    except MpvCheckError as exc:
        print(f"viewcomp check-mpv: error: {exc}", file=sys.stderr)
        return 2
    if result.ok:
        print(f"{result.version} (vo={args.vo}) runs {args.shader}")
        return 0
    said = "; ".join(result.errors[:2]) or f"exit status {result.status}"
    if result.no_output:
        print(
            f"viewcomp check-mpv: error: {result.version} (vo={args.vo}) could not open a "
            f"video output here, so {args.shader} was not tried: {said}; fix: run the "
            "check on the kiosk's display, or with --headless (a private Xvfb with "
            "software OpenGL)",
            file=sys.stderr,
        )
        return 2
    fix = (
        "export it without --param for this mpv (or use one whose libplacebo reads //!PARAM)"
        if "PARAM" in said
        else "export it again with this viewcomp (an "
        "edited or cut-short file is rejected), or check mpv's OpenGL driver"
    )
    print(
        f"viewcomp check-mpv: error: {result.version} (vo={args.vo}) rejects {args.shader} "
        f"and would play the video uncompensated: {said}; fix: {fix}; and play with "
        "export-mpv's --guard script, which stops mpv instead",
        file=sys.stderr,
    )
    return 2
