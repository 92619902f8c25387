"""The adaptive tone map's shader cost against the global one's, in one process: prints one
JSON object.

Two Compensators on the same synthetic pixel-method model at ``--size``: one draws the
global tone map (alpha, beta), the other the adaptive one (a 3 x 5 field of gain and offset,
the hue-keeping soft clip, ``--hue`` its hue weight); their draws alternate within rounds
(so that the machine's drift hits both alike), for the pixel method solved per draw and
from the view cache, RGB and yuv420p input. Per variant: the median draw time (wall ms) of
each over the rounds and the median, min and max of the per-round ratio adaptive / global::

    .venv/bin/python bench/bench_tone_shader.py --size 1920x1080 [--hue 1] > tone-shader.json
"""

from __future__ import annotations

import sys
from pathlib import Path

# The repository on sys.path: the synthetic models are tests.support's.
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import argparse
import datetime
import json
import os
import statistics
import time
from typing import Any

import numpy as np

from tests.support.synthetic import smooth_frame, synthetic_model
from viewcomp.calib.comp.adaptive import NODES
from viewcomp.calib.model.gamut import ToneField
from viewcomp.calib.world.eye import eye_from_angle
from viewcomp.rt.gl.compensator import Compensator
from viewcomp.rt.gl.context import create_context, finish
from viewcomp.rt.media.frames import rgb_to_yuv420p


def _time_pair(comps: dict[str, Compensator], ctx: Any, rounds: int, draws: int) -> dict:
    """Alternating draws of the two compensators: medians and per-round ratios."""
    times: dict[str, list[float]] = {k: [] for k in comps}
    for r in range(rounds):
        for key in ("global", "adaptive") if r % 2 == 0 else ("adaptive", "global"):
            ts = []
            for _ in range(draws):
                t = time.perf_counter()
                comps[key].draw()
                finish(ctx)
                ts.append(time.perf_counter() - t)
            times[key].append(statistics.median(ts))
    ratios = [a / g for g, a in zip(times["global"], times["adaptive"], strict=True)]
    return {
        "global_ms": round(1e3 * statistics.median(times["global"]), 2),
        "adaptive_ms": round(1e3 * statistics.median(times["adaptive"]), 2),
        "adaptive_over_global": {
            "median": round(statistics.median(ratios), 3),
            "min": round(min(ratios), 3),
            "max": round(max(ratios), 3),
        },
        "paths": [comps["global"].last_path, comps["adaptive"].last_path],
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="1920x1080")
    ap.add_argument("--rounds", type=int, default=11)
    ap.add_argument("--draws", type=int, default=7, help="draws per shader and round")
    ap.add_argument(
        "--hue",
        type=float,
        default=1.0,
        help="the field's hue weight (1: the soft clip alone, 0: the per-channel clip alone, "
        "between: both, mixed)",
    )
    args = ap.parse_args(argv)
    w, h = (int(x) for x in args.size.split("x"))
    ctx = create_context()
    report: dict[str, Any] = {
        "date": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
        "renderer": ctx.info["GL_RENDERER"], "size": args.size,
        "rounds": args.rounds, "draws": args.draws, "hue": args.hue,
        "load_avg_start": [round(x, 2) for x in os.getloadavg()],
    }  # fmt: skip
    frame = smooth_frame(w, h, seed=2)
    planes = rgb_to_yuv420p(frame, "bt709")
    rng = np.random.default_rng(0)
    field = ToneField(rng.uniform(0.4, 1.2, NODES), rng.uniform(-0.03, 0.03, NODES), args.hue)
    model = synthetic_model("pixel", w, h)
    for name, cached in (("solve", False), ("cached", True)):
        comps = {}
        for key in ("global", "adaptive"):
            c = Compensator(model, ctx, view_cache=cached, view_hold=0, view_steps=1)
            c.set_eye(*eye_from_angle(60.0, 0.5, 0.035))
            c.set_tone(0.55, 0.02)
            c.set_field(field if key == "adaptive" else None)
            comps[key] = c
        try:
            for inp in ("rgb", "yuv"):
                for c in comps.values():
                    c.upload(frame) if inp == "rgb" else c.upload_planes(planes)
                    c.draw()  # compiles (and builds the view cache)
                    c.read()
                entry = _time_pair(comps, ctx, args.rounds, args.draws)
                report[f"{name}_{inp}"] = entry
                print(f"{name}_{inp}: {entry}", file=sys.stderr)
        finally:
            for c in comps.values():
                c.release()
    report["load_avg_end"] = [round(x, 2) for x in os.getloadavg()]
    ctx.release()
    json.dump(report, sys.stdout, indent=1)
    print()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
