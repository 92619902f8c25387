"""`viewcomp calibrate` at native projector resolutions, and the player's start-up: one JSON.

For each projector grid (640x320, 1920x1080, 3840x2160 by default) a simulated capture set
(``viewcomp simulate --size WxH``: the default glossy magenta screen, 8-bit, with black
captures) is written once into ``--cache`` (not measured; reused by later runs), then
``viewcomp calibrate`` runs in a child process: its wall time, its peak resident memory
(``os.wait4``'s ``ru_maxrss`` of that child alone) and the bundle's size in MB (10^6 bytes).

``--startup WxH`` (default 1920x1080; ``none`` to skip) then measures, in a fresh child
process per run, what the live player does before its first frame, by stage: import,
``Calibration.load`` of that grid's bundle, the ``LiveRenderer`` (the per-pixel runtime
model, the tone map's set-up, the GL upload of the maps, the program), ``warm_up`` (the
shader variant compiled by an off-screen draw) and the first real frame drawn and finished
(its tone map computed synchronously, as the player's first frame is). GL is Mesa's EGL
(llvmpipe here), headless: what the player adds for its window is not in it.

Timings are this machine's and its load's (``load_average``); nothing is asserted. Run from
the repository root::

    .venv/bin/python bench/bench_calibrate.py [--sizes 640x320,1920x1080,3840x2160]
        [--cache /tmp/viewcomp-bench-calibrate] [--startup 1920x1080] [--startup-runs 3]
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
import subprocess
import time
from itertools import pairwise
from typing import Any

DEFAULT_SIZES = "640x320,1920x1080,3840x2160"


def _viewcomp(*args: str) -> list[str]:
    return [sys.executable, "-m", "viewcomp", *args]


def simulated(cache: Path, size: str) -> Path:
    """The capture set for ``size`` in ``cache``, simulated on first use (not measured)."""
    out = cache / f"captures_{size}"
    if not (out / "rig.toml").exists():
        subprocess.run(
            _viewcomp("simulate", "--size", size, "--force", str(out)),
            check=True,
            stdout=subprocess.DEVNULL,
        )
    return out


def _calibrate(cache: Path, size: str) -> dict[str, Any]:
    captures = simulated(cache, size)
    bundle = cache / f"calib_{size}.vcb"
    # One child per grid, started from here, so ru_maxrss is the calibration's alone: Popen
    # and a blocking wait4 on its pid (communicate() would reap it before wait4 could).
    t0 = time.perf_counter()
    proc = subprocess.Popen(
        _viewcomp("calibrate", str(captures), "-o", str(bundle)),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    assert proc.stderr is not None
    err = proc.stderr.read()  # until the child closes it (its exit)
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f"calibrate {size} failed ({proc.returncode}):\n{err[-2000:]!r}")
    return {
        "wall_s": round(wall, 2),
        "peak_rss_mb": round(usage.ru_maxrss / 1024, 1),
        "bundle_mb": round(bundle.stat().st_size / 1e6, 1),
        "bundle": str(bundle),
    }


def startup_child(bundle: str) -> None:
    """The measured start-up, in this (fresh) process: prints one JSON line of stage ms."""
    t = {"start": time.perf_counter()}

    from tests.support.synthetic import smooth_frame
    from viewcomp.calib.fit.calibrate import Calibration
    from viewcomp.rt.gl.context import create_context
    from viewcomp.rt.play.embed import LiveRenderer

    t["import"] = time.perf_counter()
    cpu_import = time.process_time()
    cal = Calibration.load(bundle)
    t["load_bundle"] = time.perf_counter()
    ctx = create_context()
    t["gl_context"] = time.perf_counter()
    live = LiveRenderer(cal, ctx, angle=70.0)
    t["renderer"] = time.perf_counter()
    live.warm_up(planes=False)
    t["warm_up"] = time.perf_counter()
    w, h = live.grid
    fbo = ctx.simple_framebuffer((w, h))
    live.render(smooth_frame(w, h), target=fbo, viewport=(0, 0, w, h))
    ctx.finish()
    t["first_frame"] = time.perf_counter()
    assert len(fbo.read(components=3)) == w * h * 3
    live.release()
    names = list(t)
    stages = {b: round(1000 * (t[b] - t[a]), 1) for a, b in pairwise(names)}
    stages["total_without_import"] = round(1000 * (t["first_frame"] - t["import"]), 1)
    # CPU time of the whole process (all threads, llvmpipe's included), import apart: less
    # sensitive than wall time to what else the machine runs.
    stages["cpu_without_import"] = round(1000 * (time.process_time() - cpu_import), 1)
    print(json.dumps(stages))


def _startup(bundle: Path, runs: int) -> dict[str, Any]:
    results = []
    for _ in range(runs):
        cmd = [sys.executable, __file__, "--startup-child", str(bundle)]
        r = subprocess.run(cmd, capture_output=True, text=True, check=False)
        if r.returncode != 0:
            raise SystemExit(f"start-up child failed:\n{r.stderr[-2000:]}")
        results.append(json.loads(r.stdout.strip().splitlines()[-1]))
    out = {k: round(statistics.median(r[k] for r in results), 1) for k in results[0]}
    return out | {"total_min": min(r["total_without_import"] for r in results), "runs": runs}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default=DEFAULT_SIZES, help=f"grids WxH (default {DEFAULT_SIZES})")
    ap.add_argument(
        "--cache",
        default="/tmp/viewcomp-bench-calibrate",
        help="folder for the simulated captures and bundles (kept)",
    )
    ap.add_argument("--startup", default="1920x1080", help="grid of the start-up runs, or none")
    ap.add_argument("--startup-runs", type=int, default=3)
    ap.add_argument("--startup-child", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.startup_child:
        startup_child(args.startup_child)
        return
    cache = Path(args.cache)
    cache.mkdir(parents=True, exist_ok=True)
    report: dict[str, Any] = {
        "date": datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC"),
        "cpus": os.cpu_count(),
        "load_average_start": os.getloadavg(),
        "calibrate": {},
    }
    for size in [s for s in args.sizes.split(",") if s and s != "none"]:
        simulated(cache, size)  # outside the measured run
        report["calibrate"][size] = _calibrate(cache, size)
        print(f"calibrate {size}: {report['calibrate'][size]}", file=sys.stderr)
    if args.startup != "none":
        bundle = cache / f"calib_{args.startup}.vcb"
        if not bundle.exists():
            report["calibrate"].setdefault(args.startup, _calibrate(cache, args.startup))
        report["startup_ms"] = {args.startup: _startup(bundle, args.startup_runs)}
    report["load_average_end"] = os.getloadavg()
    print(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
