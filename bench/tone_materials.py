"""The adaptive tone map against today's global rule and the paper's Eq. 21/22 on the measured
materials: plain and adapted mean CIEDE2000 of the per-pixel method compensated for the angle
seen, with the per-pixel physical limit beside them (docs/EVALUATION.md "Adaptive tone map").

    .venv/bin/python bench/tone_materials.py MATERIALS_DIR [--size 320x160] [--only NAME ...]

HDR captures, the images astronaut, coffee and chelsea, seen at 60, 90 and 125 degrees. Prints
one line per material, image and angle, then per material the means and the adaptive map's
change of the adapted error against the global rule's; writes the rows as JSON with --json.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from viewcomp.calib.comp.compensation import Compensation
from viewcomp.calib.eval.adapted import adapted_delta_e
from viewcomp.calib.eval.materials import material_files, material_world, true_limit
from viewcomp.calib.eval.metrics import delta_e2000
from viewcomp.calib.eval.testimages import natural_images
from viewcomp.calib.sim.simulator import white_screen

TONES = ("paper", "global", "adaptive")
IMAGES = ("astronaut", "coffee", "chelsea")
ANGLES = (60.0, 90.0, 125.0)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("folder")
    ap.add_argument("--size", default="320x160")
    ap.add_argument("--only", nargs="*", default=None)
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    w, h = (int(v) for v in args.size.split("x"))
    rows = []
    for path in material_files(args.folder):
        if args.only and path.stem not in args.only:
            continue
        world = material_world(path, "hdr", (w, h))
        if world.cal is None:
            print(f"{path.stem}: refused ({world.refused})", flush=True)
            continue
        sim, imgs = world.sim, natural_images(w, h)
        for iname in IMAGES:
            for angle in ANGLES:
                eye = sim.rig.viewer.eye(angle)
                ideal = sim.observe(white_screen(), imgs[iname], eye)
                row = {"material": world.name, "image": iname, "seen_at": angle}
                for tone in TONES:
                    t0 = time.perf_counter()
                    out, _ = Compensation(world.cal, "pixel", tone=tone).compensate_image(
                        imgs[iname], eye
                    )
                    seen = sim.observe(world.screen, out, eye)
                    ad = adapted_delta_e(seen, ideal)
                    row[tone] = {
                        "de": delta_e2000(seen, ideal),
                        "ade": ad.de,
                        "scale": ad.scale,
                        "seconds": time.perf_counter() - t0,
                    }
                row["limit"] = dict(
                    zip(("ade", "scale"), true_limit(sim, world.screen, eye, ideal), strict=True)
                )
                rows.append(row)
                print(
                    f"{world.name} {iname} {angle:g}: "
                    + " | ".join(
                        f"{t} de {row[t]['de']:.2f} ade {row[t]['ade']:.2f}" for t in TONES
                    )
                    + f" | limit {row['limit']['ade']:.2f}",
                    flush=True,
                )
        mine = [r for r in rows if r["material"] == world.name]
        mean = {
            t: {k: float(np.mean([r[t][k] for r in mine])) for k in ("de", "ade")} for t in TONES
        }
        lim = float(np.mean([r["limit"]["ade"] for r in mine]))
        change = mean["adaptive"]["ade"] / mean["global"]["ade"] - 1.0
        print(
            f"MEAN {world.name}: "
            + " | ".join(f"{t} de {mean[t]['de']:.2f} ade {mean[t]['ade']:.2f}" for t in TONES)
            + f" | limit {lim:.2f} | adaptive vs global ade {100 * change:+.1f} %"
            + f" | adaptive vs limit {100 * (mean['adaptive']['ade'] / lim - 1):+.1f} %",
            flush=True,
        )
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1)


if __name__ == "__main__":
    main()
