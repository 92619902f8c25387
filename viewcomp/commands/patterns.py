"""`viewcomp patterns OUT_DIR --size WxH`: the calibration patterns to project."""

from __future__ import annotations

import argparse

from viewcomp.commands._common import add_force_argument, check_output_folder, parse_size


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "patterns",
        help="write the calibration patterns to project",
        description="Write the patterns to project at the projector's resolution: Table 1's "
        "red (130,110,110), green, blue, gray (110,110,110), the ramp round(255 u/(w-1)), "
        "black, and the geometric patterns (chessboard, Gray code, phase-shifted sinusoids).",
    )
    p.add_argument("out_dir", help="folder to write (new or empty; created if needed)")
    p.add_argument("--size", required=True, help="projector resolution WIDTHxHEIGHT, e.g. 1280x720")
    add_force_argument(p, "folder of patterns")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from viewcomp.calib.io.patterns import write_patterns

    w, h = parse_size(args.size)
    check_output_folder(args.out_dir, force=args.force, what="folder of patterns")
    paths = write_patterns(args.out_dir, w, h)
    print(f"wrote {len(paths)} patterns ({w}x{h}) to {args.out_dir}")
    return 0
