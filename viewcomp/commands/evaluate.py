"""`viewcomp evaluate -o REPORT_DIR`: the paper's Section 5 in the simulator."""

from __future__ import annotations

import argparse

from viewcomp.commands._common import add_simulator_arguments


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "evaluate",
        help="reproduce the paper's evaluation in the simulator; write a report",
        description="table2: the paper's Table 2 (red/green/blue glossy screens x uniform "
        "images x seen at 90 and 60, sum of squared errors); sweep: natural images on glossy "
        "screens from 30 to 150 degrees (mean CIEDE2000). Columns: original, paper_90, "
        "paper_theta, pixel_90, pixel_theta, oracle (the simulator's true model inverted). "
        "Writes report.json, report.md and PNG plots. The default, all, is the slow one "
        "(the sweep: about 2.5 minutes at 640x320 on a 2-core machine, twice that when it is "
        "busy); --protocol table2 alone takes about half a minute.",
    )
    p.add_argument("-o", "--output", required=True, help="report folder (created if needed)")
    p.add_argument(
        "--protocol",
        choices=["table2", "sweep", "all", "materials", "audience", "hardware"],
        default="all",
        help="table2, sweep, all (both), materials: the sweep on measured materials "
        "(needs --materials), or audience: viewers spread over a zone (compensated for 90 "
        "degrees, the zone's centre, the whole audience, and each viewer alone) and a viewer "
        "walking across, followed by the face tracker; or hardware: `viewcomp capture`'s "
        "procedure on the hardware emulator (webcam, DSLR, mono12 camera; a DLP projector) "
        "on the glossy magenta screen and the materials of --materials (if given), 8-bit and "
        "HDR, calibrated and compensated, beside ideal captures by a camera of the same kind "
        "(mono or colour), with the capture time the real devices would take",
    )
    p.add_argument(
        "--no-walk", action="store_true", help="--protocol audience: the zone only, no tracked walk"
    )
    p.add_argument(
        "--materials",
        metavar="DIR",
        default=None,
        help="folder of measured materials (.npz neural BRDFs) for --protocol materials",
    )
    add_simulator_arguments(p, screen=False, gloss=False, space=True)
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(run=run)


# Seconds per protocol at 640x320, projector space, measured on this project's 2-core
# machine when otherwise idle (2026-11-24: table2 32 s, sweep 100 s, plus the report's plots).
MEASURED_S = {
    "table2": 35.0,
    "sweep": 115.0,
    "materials": 480.0,
    "audience": 300.0,
    "hardware": 240.0,  # per screen (its 6 rows: 3 cameras x 8-bit/HDR), at 320x160
}


def _estimate(args: argparse.Namespace, size: tuple[int, int] | None) -> str:
    """How long the run will take, honestly: measured times scaled by the grid's pixels."""
    parts = ["table2", "sweep"] if args.protocol == "all" else [args.protocol]
    small = args.protocol in ("materials", "hardware")  # measured at 320x160
    w, h = size or ((320, 160) if small else (640, 320))
    base = 320 * 160 if small else 640 * 320
    seconds = sum(MEASURED_S[p] for p in parts) * (w * h) / base
    if args.protocol == "hardware" and args.materials:  # glossy magenta and each material
        from viewcomp.calib.eval.materials import material_files

        seconds *= 1 + len(material_files(args.materials))
    span = f"about {seconds / 60:.1f} minutes" if seconds >= 90 else f"about {seconds:.0f} s"
    note = (
        "" if args.protocol != "all" else "; the sweep is the slow part (--protocol table2: ~35 s)"
    )
    where = "" if args.space == "projector" else "; camera space takes longer still"
    return f"{span} on an idle 2-core machine, up to twice that when busy{note}{where}"


def run(args: argparse.Namespace) -> int:
    from viewcomp.calib.errors import UsageError
    from viewcomp.calib.eval.run import run as run_eval
    from viewcomp.commands._common import Log, check_output_folder, parse_size

    check_output_folder(args.output)
    log = Log(args.quiet)
    size = parse_size(args.size) if args.size else None
    if args.protocol == "materials" and not args.materials:
        raise UsageError(
            "--protocol materials needs --materials DIR, a folder of measured materials "
            "(.npz neural BRDFs)"
        )
    log(f"evaluating protocol {args.protocol} (seed {args.seed}): {_estimate(args, size)}")
    walk = None
    if args.protocol == "audience" and not args.no_walk:
        from viewcomp.rt.track.simtrack import tracked_walk

        log("audience: tracking the simulated walk (360 camera frames)")
        walk = tracked_walk(
            progress=lambda i, n: log(f"audience: walk tracked {i}/{n}") if i % 120 == 0 else None
        )
    rep = run_eval(
        args.output,
        args.protocol,
        args.seed,
        size,
        progress=log,
        space=args.space,
        materials=args.materials,
        walk=walk,
    )
    if "hardware_checks" in rep:
        print("hardware:", rep["hardware_checks"])
    if "materials_checks" in rep:
        print("materials:", rep["materials_checks"])
    if "table2_checks" in rep:
        print("table2:", rep["table2_checks"])
    if "zone_summary" in rep:
        for name, z in rep["zone_summary"].items():
            m, w = z["mean"], z["worst"]
            print(
                f"audience {name}: mean dE 90 {m['pixel_90']:.2f}, centre "
                f"{m['pixel_centre']:.2f}, audience {m['pixel_audience']:.2f}, oracle "
                f"{m['oracle']:.2f}; worst 90 {w['pixel_90']:.2f}, audience "
                f"{w['pixel_audience']:.2f}"
            )
    if "walk" in rep:
        s = rep["walk"]["summary"]["mean"]
        print(
            f"walk: mean dE tracked {s['tracked']:.2f}, exact eye {s['exact']:.2f}, "
            f"90 degrees {s['pixel_90']:.2f}"
        )
    if "sweep_checks" in rep:
        print(
            "sweep: all criteria hold" if rep["sweep_checks"]["all"] else "sweep: some fail",
            rep["sweep_checks"],
        )
    print(f"wrote {args.output}/report.md, report.json and plots ({rep['seconds']} s)")
    return 0
