"""The audience's cost in the shader against one eye's, in one process: prints one JSON object.

Per draw at ``--size`` (default 1920x1080), RGB input, one Compensator: the median wall ms
over ``--rounds`` rounds (the variants alternating within each round, so the machine's drift
hits them alike) of

- ``held_eye``: one eye held still: drawn from the view cache;
- ``held_audience``: ``--viewers`` viewers held still: drawn from the view cache, which holds
  their combined solve, so it should cost what ``held_eye`` does;
- ``moving_eye``: the eye moves every draw: the full per-pixel solve;
- ``moving_audience``: the audience moves every draw: the normal equations of every viewer
  per pixel, per draw;
- ``build_eye`` / ``build_audience``: building the view cache once (one band).

And the per-round ratios held_audience / held_eye (median, min, max). Run::

    .venv/bin/python bench/bench_audience.py > audience.json
"""

from __future__ import annotations

import sys
from pathlib import Path

# The repository on sys.path: the synthetic models and calibrations are tests.support's.
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import argparse
import datetime
import json
import os
import statistics
import time

import numpy as np

from tests.support.synthetic import smooth_frame, synthetic_model
from viewcomp.calib.world.audience import zone
from viewcomp.calib.world.eye import eye_from_angle
from viewcomp.rt.gl.compensator import Compensator
from viewcomp.rt.gl.context import create_context, finish

D, HT = 0.5, 0.035


def _report(
    args: argparse.Namespace,
    size: tuple[int, int],
    renderer: object,
    load0: tuple[float, float, float],
    times: dict[str, list[float]],
    ratios: list[float],
) -> dict[str, object]:
    """The JSON report of a run: the set-up, the machine and the medians."""
    w, h = size
    return {
        "when": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "size": [w, h],
        "viewers": args.viewers,
        "rounds": args.rounds,
        "draws_per_round": args.draws,
        "machine": {
            "cpus": os.cpu_count(),
            "gl": renderer,
            "load_start": [round(v, 2) for v in load0],
            "load_end": [round(v, 2) for v in os.getloadavg()],
        },
        "median_ms": {k: round(statistics.median(v), 2) for k, v in times.items()},
        "held_audience_over_held_eye": {
            "median": round(statistics.median(ratios), 3),
            "min": round(min(ratios), 3),
            "max": round(max(ratios), 3),
        },
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="1920x1080")
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--draws", type=int, default=5, help="draws per variant and round")
    ap.add_argument("--viewers", type=int, default=7, help="viewers of the audience (<= 16)")
    args = ap.parse_args(argv)
    w, h = (int(v) for v in args.size.lower().split("x"))
    load0 = os.getloadavg()
    ctx = create_context()
    model = synthetic_model("pixel", w, h, seed=3)
    frame = smooth_frame(w, h, seed=5)
    eye = eye_from_angle(75.0, D, HT)
    aud = zone(60.0, 120.0, args.viewers, D, HT)
    times: dict[str, list[float]] = {}
    ratios: list[float] = []
    out = np.empty((h, w, 3), np.uint8)

    def timed(comp: Compensator, key: str, setup) -> float:
        samples = []
        for i in range(args.draws):
            setup(i)
            comp.upload(frame)
            t = time.perf_counter()
            comp.draw()
            finish(ctx)
            samples.append(time.perf_counter() - t)
            comp.read(out)
        ms = 1e3 * statistics.median(samples)
        times.setdefault(key, []).append(ms)
        return ms

    with Compensator(model, ctx, view_hold=0, view_steps=1) as comp:
        comp.set_tone(0.6, 0.01)
        for _ in range(args.rounds):
            # A cache build is the first draw at a new view; time it alone.
            for key, view in (("build_eye", eye), ("build_audience", aud)):
                comp.set_eye(0.0, 0.0, 1.0)
                comp.render(frame, out)  # another view first: the next draw builds anew
                if key == "build_eye":
                    comp.set_eye(*view)
                else:
                    comp.set_audience(view)
                comp.upload(frame)
                t = time.perf_counter()
                comp.draw()
                finish(ctx)
                times.setdefault(key, []).append(1e3 * (time.perf_counter() - t))
                comp.read(out)
            comp.set_eye(*eye)
            comp.render(frame, out)
            e_ms = timed(comp, "held_eye", lambda i: None)
            assert comp.last_path == "cached"
            comp.set_audience(aud)
            comp.render(frame, out)
            a_ms = timed(comp, "held_audience", lambda i: None)
            assert comp.last_path == "cached"
            ratios.append(a_ms / e_ms)
            comp.view_cache = False
            timed(comp, "moving_eye", lambda i: comp.set_eye(*eye_from_angle(60 + i, D, HT)))
            timed(
                comp,
                "moving_audience",
                lambda i: comp.set_audience(zone(60.0 + i, 120.0, args.viewers, D, HT)),
            )
            assert comp.last_path == "audience"
            comp.view_cache = True
    renderer = ctx.info.get("GL_RENDERER")
    ctx.release()
    report = _report(args, (w, h), renderer, load0, times, ratios)
    json.dump(report, sys.stdout, indent=1)
    print()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
