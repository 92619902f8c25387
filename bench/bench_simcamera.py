"""The simulated calibration camera's render time at full size: prints one JSON object.

One 1280x720 capture of the gray pattern on a glossy magenta screen (the camera rig of
`viewcomp simulate --space camera`), after a warm-up; per round the mean of ``--captures``
captures. On a shared machine the figure varies with whoever else runs: compare rounds of
one run, never against a fixed number. Run from the repository root::

    .venv/bin/python bench/bench_simcamera.py [--rounds 3] [--captures 3]
"""

from __future__ import annotations

import argparse
import datetime
import json
import statistics
import time

from viewcomp.calib.io.patterns import table1_patterns
from viewcomp.calib.sim.simcamera import SimCamera, camera_rig
from viewcomp.calib.sim.simulator import Simulator, make_screen, simulation_rig


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=3, help="rounds (default 3)")
    ap.add_argument("--captures", type=int, default=3, help="captures per round (default 3)")
    args = ap.parse_args(argv)
    rig = camera_rig(simulation_rig())
    cam = SimCamera(Simulator(rig=rig))
    _ = cam.view  # the per-rig geometry, once
    w, h = rig.projector.resolution
    gray = table1_patterns(w, h)["gray"]
    screen = make_screen("magenta", "glossy")
    cam.capture(screen, gray, "warm-up")
    rounds = []
    for r in range(args.rounds):
        t0 = time.perf_counter()
        for k in range(args.captures):
            cam.capture(screen, gray, f"r{r}k{k}")
        rounds.append(1e3 * (time.perf_counter() - t0) / args.captures)
    cw, ch = rig.camera.resolution
    print(
        json.dumps(
            {
                "bench": "simcamera",
                "utc": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
                "camera": f"{cw}x{ch}",
                "ms_per_capture_median": round(statistics.median(rounds), 1),
                "ms_per_capture_rounds": [round(x, 1) for x in rounds],
            }
        )
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
