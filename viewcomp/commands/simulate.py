"""`viewcomp simulate OUT_DIR`: a capture set from the built-in simulator."""

from __future__ import annotations

import argparse

from viewcomp.calib.errors import UsageError
from viewcomp.commands._common import (
    add_force_argument,
    add_simulator_arguments,
    check_output_folder,
    parse_size,
    simulated_screen,
)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "simulate",
        help="write a capture set from the simulated projector, screen and camera",
        description="Simulate a projector, a screen and a camera and write the capture set "
        "that `viewcomp capture` would write for real hardware: rig.toml, white/ (ideal "
        "matte white screen) and screen/ (the real one: an analytic screen, or a measured "
        "material with --material). Seeded and reproducible.",
    )
    p.add_argument(
        "out_dir",
        help="capture-set folder to write (new or empty; an old capture set with --force)",
    )
    add_simulator_arguments(p, space=True, material=True)
    p.add_argument("--no-black", action="store_true", help="leave out the optional black captures")
    p.add_argument(
        "--hdr",
        action="store_true",
        help="bracket every capture (relative exposures 1, 1/4, 1/16, 1/64, 1/256) and merge "
        "the 8-bit frames into float32 linear .npy captures",
    )
    p.add_argument(
        "--exposure",
        default=None,
        metavar="auto|X",
        help="the camera's exposure: a number > 0 (linear gain), or auto: 8-bit, the highest "
        "at which no capture of either screen clips (<= 0.98 of full scale); --hdr, the one "
        "that puts the white screen's gray at 0.5 of full scale (default: auto with --hdr, "
        "0.8 otherwise)",
    )
    add_force_argument(p, "capture set")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    import math
    from dataclasses import replace

    from viewcomp.calib.io.hdr import DEFAULT_STOPS
    from viewcomp.calib.sim.simulate import simulate_capture_set
    from viewcomp.calib.sim.simulator import PROJECTOR_PRESETS, simulation_rig

    colour, gloss, material, projector = simulated_screen(args)
    exposure: float | str | None = args.exposure
    if exposure is not None and exposure != "auto":
        try:
            exposure = float(exposure)
        except ValueError:
            exposure = math.nan
        if not (math.isfinite(exposure) and exposure > 0):
            raise UsageError(f"--exposure is auto or a number > 0, got {args.exposure!r}")
    check_output_folder(args.out_dir, force=args.force, what="capture set")
    rig = simulation_rig()
    if args.size:
        w, h = parse_size(args.size)
        rig = replace(rig, projector=replace(rig.projector, resolution=(w, h)))
        if args.space == "camera":  # keep the camera's pixels per projector pixel
            from viewcomp.calib.sim.simcamera import scaled_camera_rig

            rig = scaled_camera_rig(rig, (w, h))
    paths = simulate_capture_set(
        args.out_dir,
        colour,
        gloss,
        args.space,
        args.seed,
        rig=rig,
        black=not args.no_black,
        material=material,
        projector=PROJECTOR_PRESETS[projector],
        exposure=exposure,
        hdr_stops=DEFAULT_STOPS if args.hdr else None,
        log=print,
    )
    kind = "HDR float32 linear" if args.hdr else "8-bit"
    print(
        f"wrote a simulated capture set ({len(paths)} files, {args.space} space, {kind}) to "
        f"{args.out_dir}"
    )
    return 0
