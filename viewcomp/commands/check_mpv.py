"""`viewcomp check-mpv SHADER`: does the installed mpv run this exported shader?"""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from viewcomp.rt.export.mpv_check import MpvCheck


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "check-mpv",
        help="check that the installed mpv runs an exported shader as exported (exit 2 if not)",
        description="Check that SHADER holds every texture whole, run the installed mpv on "
        "the export's test still through it (with export-mpv's guard script; on this "
        "display, or a private Xvfb with --headless or without one) and compare a "
        "screenshot of the window with the check value the export carries. mpv skips a "
        "shader it cannot parse or compile, and silently a hook whose textures are missing, "
        "and plays uncompensated with exit status 0; this exits with status 2 and what "
        "failed instead. "
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


def _picture(args: argparse.Namespace, result: MpvCheck) -> int:
    """mpv ran the file without an error: compare its output with the export's check value
    (status 2 on a mismatch; 0 with a note when the file carries none)."""
    from viewcomp.rt.export.mpv_check import TOLERANCE

    said = f"{result.version} (vo={args.vo})"
    if result.expected is None:
        print(
            f"{said} runs {args.shader} without an error; note: the picture could not be "
            "verified: the file carries no check value (exported before viewcomp wrote "
            "one; export it again to have the picture checked)"
        )
        return 0
    if result.measured is None:  # a file that says what mpv must show, and no picture
        size = next(a for a in result.command if a.startswith("--geometry=")).split("=")[1]
        print(
            f"viewcomp check-mpv: error: {said} ran {args.shader} but gave no screenshot of "
            f"its window at the grid's size {size}, so the "
            "picture could not be verified; fix: check with --headless (a private Xvfb), "
            "or on a display at least the grid's size",
            file=sys.stderr,
        )
        return 2
    assert result.measured is not None and result.expected is not None
    diff = np.abs(result.measured - result.expected)
    worst = np.unravel_index(int(np.argmax(diff)), diff.shape)
    numbers = (
        f"block (row {worst[0]}, column {worst[1]}) channel {'RGB'[worst[2]]}: measured "
        f"{result.measured[worst]:.2f}, expected {result.expected[worst]:.2f}; mean "
        f"difference {diff.mean():.2f} levels, tolerance {TOLERANCE:g}"
    )
    if result.picture_ok:
        print(
            f"{said} runs {args.shader} as exported (test still: max difference "
            f"{diff.max():.2f} levels, tolerance {TOLERANCE:g})"
        )
        return 0
    print(
        f"viewcomp check-mpv: error: {said} loads {args.shader} but the hook did not run as "
        f"exported: its output for the test still differs from the file's check value "
        f"({numbers}); mpv would play the video wrongly compensated or uncompensated; fix: "
        "export it again with this viewcomp (an edited file fails), or check mpv's OpenGL "
        "driver and that nothing scales the window (--geometry, a window manager)",
        file=sys.stderr,
    )
    return 2


def run(args: argparse.Namespace) -> int:
    from viewcomp.rt.export.mpv_check import MpvCheckError, check_mpv

    try:
        result = check_mpv(args.shader, vo=args.vo, headless=args.headless)
    except MpvCheckError as exc:
        print(f"viewcomp check-mpv: error: {exc}", file=sys.stderr)
        return 2
    if result.problems:
        print(
            f"viewcomp check-mpv: error: {args.shader} is cut short or edited: "
            f"{'; '.join(result.problems[:4])}; mpv would skip its hook and play the video "
            "uncompensated; fix: export it again with `viewcomp export-mpv` (and copy it whole)",
            file=sys.stderr,
        )
        return 2
    if result.ok:
        return _picture(args, result)
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
