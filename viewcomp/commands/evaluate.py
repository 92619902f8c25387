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
        "Writes report.json, report.md and PNG plots. `all` takes a few minutes.",
    )
    p.add_argument("-o", "--output", required=True, help="report folder (created if needed)")
    p.add_argument("--protocol", choices=["table2", "sweep", "all"], default="all")
    add_simulator_arguments(p, screen=False, gloss=False, space=True)
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from viewcomp.calib.eval.run import run as run_eval
    from viewcomp.commands._common import Log, check_output_folder, parse_size

    check_output_folder(args.output)
    log = Log(args.quiet)
    size = parse_size(args.size) if args.size else None
    log(f"evaluating protocol {args.protocol} (seed {args.seed})")
    rep = run_eval(args.output, args.protocol, args.seed, size, progress=log, space=args.space)
    if "table2_checks" in rep:
        print("table2:", rep["table2_checks"])
    if "sweep_checks" in rep:
        print("sweep: all criteria hold" if rep["sweep_checks"]["all"] else "sweep: some fail",
              rep["sweep_checks"])  # fmt: skip
    print(f"wrote {args.output}/report.md, report.json and plots ({rep['seconds']} s)")
    return 0
