"""Measured materials in the simulator: prints one JSON object to stdout.

Per material of a folder of measured materials (the neural-BRDF ``.npz`` files): the time of
one :meth:`Simulator.reflectance` (the lens-averaged BRDF over the projector grid, 16 lens
samples, float64; wall and CPU seconds), the highlight as
the calibration camera sees it (peak over diffuse of the gray capture, per channel, and the
peak relative to the white screen's gray), and the exposure ``simulate --exposure auto``
chooses in 8 bits (nothing clips) and for HDR. Timings vary with whoever else uses the
machine: compare materials of one run, never against a fixed number. Run from the repository
root::

    .venv/bin/python bench/bench_materials.py MATERIALS_DIR [--size 640x320]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from viewcomp.calib.io.patterns import table1_patterns
from viewcomp.calib.sim.simulate import choose_exposure
from viewcomp.calib.sim.simulator import (
    DLP_PROJECTOR,
    Simulator,
    material_screen,
    simulation_rig,
    white_screen,
)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("materials", type=Path, help="folder of material .npz files")
    parser.add_argument("--size", default="640x320", help="projector grid WxH")
    args = parser.parse_args(argv)
    w, h = (int(v) for v in args.size.split("x"))
    rig = simulation_rig()
    rig = replace(rig, projector=replace(rig.projector, resolution=(w, h), principal_point=None))
    sim = Simulator(rig=rig, projector=DLP_PROJECTOR)
    gray = table1_patterns(w, h)["gray"]
    eye = sim.geometry.camera
    white_gray = sim.expose(sim.radiance(white_screen(), gray, eye), vignetting=True)
    out: dict[str, object] = {"size": [w, h], "materials": {}}
    for path in sorted(args.materials.glob("*.npz")):
        screen = material_screen(path)
        t0, c0 = time.perf_counter(), time.process_time()
        refl = sim.reflectance(screen, eye)
        seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
        seen = sim.expose(sim.radiance(screen, gray, eye), vignetting=True)
        peak = seen.max(axis=(0, 1))
        out["materials"][path.stem] = {  # type: ignore[index]
            "reflectance_s": round(seconds, 3),
            "reflectance_cpu_s": round(cpu, 3),
            "reflectance_peak": refl.max(axis=(0, 1)).round(3).tolist(),
            "diffuse_albedo": screen.diffuse.round(4).tolist(),
            "gray_peak_over_median": (peak / np.median(seen, axis=(0, 1))).round(1).tolist(),
            "gray_peak_over_white_gray": round(float(peak.max() / np.median(white_gray)), 2),
            "exposure_auto_8bit": round(choose_exposure(sim, None, screen, True, None), 4),
            "exposure_auto_hdr": round(choose_exposure(sim, None, screen, True, (1.0,)), 4),
        }
    json.dump(out, sys.stdout, indent=1)
    print()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
