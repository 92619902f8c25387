"""`viewcomp simulate OUT_DIR`: a capture set from the built-in simulator."""

from __future__ import annotations

import argparse

from viewcomp.commands._common import (
    add_force_argument,
    add_simulator_arguments,
    check_output_folder,
    parse_size,
    screen_colour,
)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "simulate",
        help="write a capture set from the simulated projector, screen and camera",
        description="Simulate a projector, a screen and a camera and write the capture set "
        "that `viewcomp capture` would write for real hardware: rig.toml, white/ (ideal "
        "matte white screen) and screen/ (the real one). Seeded and reproducible.",
    )
    p.add_argument(
        "out_dir",
        help="capture-set folder to write (new or empty; an old capture set with --force)",
    )
    add_simulator_arguments(p, space=True)
    p.add_argument("--no-black", action="store_true", help="leave out the optional black captures")
    add_force_argument(p, "capture set")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from viewcomp.calib.sim.simulate import simulate_capture_set
    from viewcomp.calib.sim.simulator import simulation_rig

    screen = screen_colour(args.screen)
    check_output_folder(args.out_dir, force=args.force, what="capture set")
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
