"""What the bundle's compact maps cost in output: full float32 maps against the bundle's.

For each simulated screen (analytic ones and measured materials read from
``--materials``, never copied), a capture set at ``--size`` is simulated into ``--cache``
(once), calibrated in memory (float32 maps, the "full precision" calibration), saved as a
bundle and loaded again (the compact maps of :mod:`viewcomp.calib.io.compact`). Both run
``viewcomp.calib.model.reference.compensate`` (the per-pixel method) on the natural test
images plus a saturated red and a dark purple, at eyes of 60, 90 and 120 degrees, with the
full calibration's tone map for both (so only the maps differ). Printed per screen: the
largest difference in 8-bit levels, its 99.9th percentile, how many pixel-channels differ by
more than 1 and by any, and the bundle's size. One JSON object; nothing is asserted.

    .venv/bin/python bench/bench_compact.py [--size 640x320] [--cache /tmp/viewcomp-bench-compact]
        [--materials DIR]   (default: shared/data/materials beside the repository)
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from viewcomp.calib.comp.compensation import Compensation, thumbnail
from viewcomp.calib.eval.testimages import natural_images, uniform
from viewcomp.calib.fit.calibrate import Calibration, calibrate
from viewcomp.calib.io.captureset import read_capture_set
from viewcomp.calib.model.reference import compensate

# name -> `viewcomp simulate` options ({m}: the materials folder)
SCREENS = {
    "magenta-glossy": [],
    "textured-glossy": ["--screen", "textured"],
    "yellow-satin": ["--screen", "yellow", "--gloss", "satin"],
    "green-plastic-hdr": ["--material", "{m}/green-plastic.npz", "--hdr"],
    "red-specular-plastic-hdr": ["--material", "{m}/red-specular-plastic.npz", "--hdr"],
    "satin-gold-hdr": ["--material", "{m}/satin_gold.npz", "--hdr"],
}


def compare(full: Calibration, compact: Calibration) -> dict[str, Any]:
    """Level differences of the per-pixel reference output, full maps vs compact ones."""
    h, w = full.shape
    images = natural_images(w, h) | {
        "red": uniform((200, 30, 30), w, h),
        "dark": uniform((20, 10, 40), w, h),
    }
    comp = Compensation(full, "pixel")
    model = compact.pixel.runtime_model()
    diffs = []
    for img in images.values():
        for angle in (60.0, 90.0, 120.0):
            eye = full.eye(angle=angle)
            p = comp(thumbnail(img), eye)
            a = compensate(p.model, img, eye, p.alpha, p.beta)
            b = compensate(model, img, eye, p.alpha, p.beta)
            diffs.append(np.abs(a.astype(np.int16) - b).ravel())
    d = np.concatenate(diffs)
    return {
        "max_levels": int(d.max()),
        "p99.9_levels": float(np.percentile(d, 99.9)),
        "over_1_level": int(np.count_nonzero(d > 1)),
        "any_difference": int(np.count_nonzero(d)),
        "pixel_channels": int(d.size),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", default="640x320")
    ap.add_argument("--cache", default="/tmp/viewcomp-bench-compact")
    beside = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "materials"
    ap.add_argument("--materials", default=str(beside), help="folder of measured materials")
    ap.add_argument("--screens", default=",".join(SCREENS), help="names, comma-separated")
    args = ap.parse_args()
    cache = Path(args.cache)
    report: dict[str, Any] = {"size": args.size, "screens": {}}
    for name in args.screens.split(","):
        caps = cache / f"{name}_{args.size}"
        if not (caps / "rig.toml").exists():
            opts = [o.format(m=args.materials) for o in SCREENS[name]]
            cmd = [sys.executable, "-m", "viewcomp", "simulate", "--size", args.size, *opts]
            subprocess.run([*cmd, "--force", str(caps)], check=True, stdout=subprocess.DEVNULL)
        full = calibrate(read_capture_set(caps))
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "cal.vcb"
            full.save(path)
            size_mb = path.stat().st_size / 1e6
            compact = Calibration.load(path)
        report["screens"][name] = compare(full, compact) | {"bundle_mb": round(size_mb, 2)}
        print(name, report["screens"][name], file=sys.stderr, flush=True)
    print(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
