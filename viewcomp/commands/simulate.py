"""`viewcomp simulate OUT_DIR`: a capture set from the built-in simulator."""

from __future__ import annotations

import argparse

from viewcomp.commands._common import parse_rgb, parse_size


def register(sub: argparse._SubParsersAction) -> None:
    from viewcomp.calib.sim.simulator import GLOSS_PRESETS, SCREEN_COLOURS

    p = sub.add_parser(
        "simulate",
        help="write a capture set from the simulated projector, screen and camera",
        description="Simulate a projector, a screen and a camera and write the capture set "
        "that `viewcomp capture` would write for real hardware: rig.toml, white/ (ideal "
        "matte white screen) and screen/ (the real one). Seeded and reproducible.",
    )
    p.add_argument("out_dir", help="capture-set folder to write (new, or an old capture set)")
    p.add_argument(
        "--screen",
        default="magenta",
        help=f"screen colour: {', '.join(SCREEN_COLOURS)}, or R,G,B albedos in 0..1 "
        "(default: magenta)",
    )
    p.add_argument(
        "--gloss", default="glossy", choices=sorted(GLOSS_PRESETS), help="default: glossy"
    )
    p.add_argument(
        "--space",
        default="projector",
        choices=["projector", "camera"],
        help="projector: images already on the projector grid; camera: raw camera frames "
        "(default: projector)",
    )
    p.add_argument("--seed", type=int, default=0, help="noise seed (default 0)")
    p.add_argument(
        "--size", default=None, help="projector resolution WxH (default 640x320, the paper's)"
    )
    p.add_argument("--no-black", action="store_true", help="leave out the optional black captures")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from viewcomp.calib.sim.simulate import simulate_capture_set
    from viewcomp.calib.sim.simulator import SCREEN_COLOURS, simulation_rig

    screen = args.screen if args.screen in SCREEN_COLOURS else parse_rgb(args.screen)
    rig = simulation_rig()
    if args.size:
        w, h = parse_size(args.size)
        rig = replace(rig, projector=replace(rig.projector, resolution=(w, h)))
        if args.space == "camera":  # keep the camera's pixels per projector pixel
            from viewcomp.calib.sim.simcamera import scaled_camera_rig

            rig = scaled_camera_rig(rig, (w, h))
    paths = simulate_capture_set(
        args.out_dir, screen, args.gloss, args.space, args.seed, rig=rig, black=not args.no_black
    )
    print(
        f"wrote a simulated capture set ({len(paths)} files, {args.space} space) to {args.out_dir}"
    )
    return 0
