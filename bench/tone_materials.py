"""The adaptive tone map against today's global rule and the paper's Eq. 21/22 on the measured
materials: plain and adapted mean CIEDE2000 of the per-pixel method compensated for the angle
seen, with the per-pixel physical limit beside them (docs/EVALUATION.md "Adaptive tone map").

    .venv/bin/python bench/tone_materials.py MATERIALS_DIR [--size 320x160] [--only NAME ...]
    .venv/bin/python bench/tone_materials.py --analytic [--size 320x160] [--only red ...]

HDR captures (the analytic screens: the sweep protocol's own captures), the images astronaut,
coffee and chelsea, seen at 60, 90 and 125 degrees. Prints one line per screen, image and
angle, then per screen the means and the adaptive map's change of the adapted error against
the global rule's; writes the rows as JSON with --json.
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Iterator

import numpy as np

from viewcomp.calib.comp.compensation import Compensation
from viewcomp.calib.eval.adapted import adapted_delta_e
from viewcomp.calib.eval.evaluate import SWEEP_SCREENS, World
from viewcomp.calib.eval.materials import material_files, material_world, true_limit
from viewcomp.calib.eval.metrics import delta_e2000
from viewcomp.calib.eval.testimages import natural_images
from viewcomp.calib.fit.calibrate import Calibration
from viewcomp.calib.sim.simulator import Screen, Simulator, white_screen

TONES = ("paper", "global", "adaptive")
IMAGES = ("astronaut", "coffee", "chelsea")
ANGLES = (60.0, 90.0, 125.0)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("folder", nargs="?", default=None, help="the measured materials' folder")
    ap.add_argument(
        "--analytic",
        action="store_true",
        help="the sweep protocol's analytic glossy screens (red, green, blue, magenta) instead",
    )
    ap.add_argument("--size", default="320x160")
    ap.add_argument("--only", nargs="*", default=None)
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    if not args.analytic and args.folder is None:
        ap.error("give the measured materials' folder, or --analytic")
    w, h = (int(v) for v in args.size.split("x"))
    rows: list[dict] = []
    for world_name, cal, sim, screen in worlds(args, (w, h)):
        rows += compare(world_name, cal, sim, screen)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1)


def worlds(args: argparse.Namespace, size: tuple[int, int]) -> Iterator[tuple]:
    """(name, calibration, simulator, screen) per measured material of the folder (HDR
    captures), or with ``--analytic`` per analytic screen of the sweep protocol."""
    if args.analytic:
        world = World.make(seed=0, size=size)
        for name in SWEEP_SCREENS:
            if args.only and name not in args.only:
                continue
            case = world.case(name)
            yield name, case.cal, world.sim, case.screen
        return
    for path in material_files(args.folder):
        if args.only and path.stem not in args.only:
            continue
        mat = material_world(path, "hdr", size)
        if mat.cal is None:
            print(f"{path.stem}: refused ({mat.refused})", flush=True)
            continue
        yield mat.name, mat.cal, mat.sim, mat.screen


def compare(name: str, cal: Calibration, sim: Simulator, screen: Screen) -> list[dict]:
    """The three tone maps and the per-pixel limit on one screen: a row per image and angle
    (printed as it is measured), then the screen's means printed."""
    h, w = cal.shape
    imgs, rows = natural_images(w, h), []
    for iname in IMAGES:
        for angle in ANGLES:
            eye = sim.rig.viewer.eye(angle)
            ideal = sim.observe(white_screen(), imgs[iname], eye)
            row: dict = {"material": name, "image": iname, "seen_at": angle}
            for tone in TONES:
                t0 = time.perf_counter()
                out, _ = Compensation(cal, "pixel", tone=tone).compensate_image(imgs[iname], eye)
                seen = sim.observe(screen, out, eye)
                ad = adapted_delta_e(seen, ideal)
                row[tone] = {
                    "de": delta_e2000(seen, ideal),
                    "ade": ad.de,
                    "scale": ad.scale,
                    "seconds": time.perf_counter() - t0,
                }
            lim = true_limit(sim, screen, eye, ideal)
            row["limit"] = dict(zip(("ade", "scale"), lim, strict=True))
            rows.append(row)
            print(
                f"{name} {iname} {angle:g}: "
                + " | ".join(f"{t} de {row[t]['de']:.2f} ade {row[t]['ade']:.2f}" for t in TONES)
                + f" | limit {row['limit']['ade']:.2f}",
                flush=True,
            )
    mean = {t: {k: float(np.mean([r[t][k] for r in rows])) for k in ("de", "ade")} for t in TONES}
    lim_mean = float(np.mean([r["limit"]["ade"] for r in rows]))
    change = mean["adaptive"]["ade"] / mean["global"]["ade"] - 1.0
    print(
        f"MEAN {name}: "
        + " | ".join(f"{t} de {mean[t]['de']:.2f} ade {mean[t]['ade']:.2f}" for t in TONES)
        + f" | limit {lim_mean:.2f} | adaptive vs global ade {100 * change:+.1f} %"
        + f" | adaptive vs limit {100 * (mean['adaptive']['ade'] / lim_mean - 1):+.1f} %",
        flush=True,
    )
    return rows


if __name__ == "__main__":
    main()
