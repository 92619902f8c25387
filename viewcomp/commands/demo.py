"""`viewcomp demo`: the main job end to end on a built-in example, no arguments needed."""

from __future__ import annotations

import argparse
from pathlib import Path

DEMO_ANGLES = (45, 60, 90, 120, 135)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "demo",
        help="simulate, calibrate and compensate a built-in example; write a picture",
        description="End to end without hardware: a simulated glossy magenta screen is "
        "captured and calibrated, natural images are compensated for several viewing angles "
        "with both methods, and what a viewer would see at each angle is written side by "
        "side (ideal white screen | uncompensated | paper | per-pixel).",
    )
    p.add_argument("--out", default="viewcomp-demo", help="output folder (default ./viewcomp-demo)")
    p.add_argument("--screen", default="magenta", help="simulated screen colour (default magenta)")
    p.add_argument("--seed", type=int, default=0)
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    import cv2
    import numpy as np

    from viewcomp.calib.calibrate import Calibration, calibrate
    from viewcomp.calib.capture import read_capture_set
    from viewcomp.calib.compensation import Compensation
    from viewcomp.calib.imageio import write_png
    from viewcomp.calib.metrics import delta_e2000
    from viewcomp.calib.simulate import simulate_capture_set, simulation_rig
    from viewcomp.calib.simulator import Simulator, make_screen, white_screen
    from viewcomp.calib.testimages import natural_images
    from viewcomp.commands._common import Log

    log = Log()
    out = Path(args.out)
    caps = out / "captures"
    log(f"simulating a glossy {args.screen} screen: capture set in {caps}")
    simulate_capture_set(caps, args.screen, "glossy", seed=args.seed)
    log("calibrating both methods")
    cal = calibrate(read_capture_set(caps))
    bundle = out / f"{args.screen}.vcb"
    cal.save(bundle)
    cal = Calibration.load(bundle)
    log(f"wrote the calibration bundle {bundle}")

    sim = Simulator(rig=simulation_rig(), seed=args.seed)
    screen = make_screen(args.screen, "glossy", shape=sim.shape, seed=args.seed)
    h, w = sim.shape
    images = dict(list(natural_images(w, h).items())[:2])
    comps = {m: Compensation(cal, m) for m in ("paper", "pixel")}
    rows, table = [], []
    for iname, image in images.items():
        for angle in DEMO_ANGLES:
            eye = cal.eye(angle)
            ideal = sim.observe(white_screen(), image, eye)
            tiles = {
                "white screen (ideal)": ideal,
                "uncompensated": sim.observe(screen, image, eye),
            }
            for m, comp in comps.items():
                img, _ = comp.compensate_image(image, eye)
                tiles[f"{m} method"] = sim.observe(screen, img, eye)
            de = {k: delta_e2000(v, ideal) for k, v in tiles.items()}
            table.append((iname, angle, de))
            labelled = []
            for k, v in tiles.items():
                t = v.copy()
                text = f"{k} @{angle}" + ("" if k.startswith("white") else f" dE {de[k]:.1f}")
                cv2.putText(t, text, (8, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (255, 255, 255),
                            2, cv2.LINE_AA)  # fmt: skip
                labelled.append(t)
            rows.append(np.concatenate(labelled, axis=1))
        log(f"compensated {iname} for angles {', '.join(map(str, DEMO_ANGLES))}")
    grid = np.concatenate(rows, axis=0)
    grid = cv2.resize(grid, None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA)
    picture = out / "demo.png"
    write_png(picture, grid)
    print("\nmean CIEDE2000 against the white screen (lower is better):")
    print(f"{'image':>10} {'angle':>5} {'uncompensated':>14} {'paper':>7} {'per-pixel':>9}")
    for iname, angle, de in table:
        print(f"{iname:>10} {angle:>5} {de['uncompensated']:>14.2f} {de['paper method']:>7.2f} "
              f"{de['pixel method']:>9.2f}")  # fmt: skip
    print(f"\nside-by-side picture (what a viewer sees at each angle): {picture.resolve()}")
    return 0
