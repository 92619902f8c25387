"""The mpv export's size and mpv's load time per grid and storage: prints one JSON object.

For each projector grid (640x320 and 1920x1080 by default; a simulated glossy magenta
screen calibrated by :func:`tests.support.calibrations.small_calibration`, or ``--calib``
bundles) and each way of storing the maps (``viewcomp export-mpv --precision``: 16, 8 and
32 for the fixed angle; ``maps16``: the 8 eye-following maps of ``--param`` with the angle
a constant, as the fixed-angle export was stored before it folded the eye in), it exports
the shader at 60 degrees and runs Debian's mpv (``--vo=gpu``, Mesa's software OpenGL on a
private Xvfb) for one frame of a short clip at the grid's size, with and without the
shader, ``--runs`` times in turn. Per variant: the file's size (MB), the median wall time
to the first frame with the shader and without, and the load time (their difference: what
the shader adds).
Timings are this machine's and its load's (see ``load_average``); never asserted.

Run from the repository root (the 1080p calibration takes about 16 s and 0.9 GB)::

    .venv/bin/python bench/bench_mpv.py [--grids 640x320,1920x1080] [--runs 3]
        [--calib 640x320=a.vcb --calib 1920x1080=b.vcb]
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
import tempfile
import time
from typing import Any

from tests.support.calibrations import small_calibration
from tests.support.synthetic import smooth_frame, write_clip
from viewcomp.calib.fit.calibrate import Calibration
from viewcomp.rt.export.mpv import export_mpv_shader
from viewcomp.rt.play.xvfb import Xvfb

VARIANTS = {"16": {"precision": 16}, "8": {"precision": 8}, "32": {"precision": 32},
            "maps16": {"precision": 16, "param": True}}  # fmt: skip


def without_param(text: str, angle: float) -> str:
    """The ``--param`` export with its ``//!PARAM`` replaced by a constant, which Debian's
    mpv loads: the 8 maps of the eye-following hook, as the fixed-angle export stored them
    before it folded the eye in (the "before" of docs/PLAYER.md's sizes)."""
    start, end = text.index("//!PARAM"), text.index("//!HOOK")
    text = text[:start] + text[end:]
    desc = text.index("\n", text.index("//!DESC")) + 1
    return text[:desc] + f"const float angle = {angle:.1f};\n" + text[desc:]


def first_frame_s(clip: Path, shader: Path | None) -> float:
    """Wall seconds for mpv to start, show the clip's first frame and quit."""
    cmd = ["mpv", "--no-config", "--vo=gpu", "--gpu-context=x11egl", "--gpu-sw", "--frames=1",
           "--audio=no", "--osc=no", "--msg-level=all=error", str(clip)]  # fmt: skip
    if shader is not None:
        cmd.insert(-1, f"--glsl-shaders={shader}")
    t0 = time.monotonic()
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    dt = time.monotonic() - t0
    if p.returncode != 0 or "[vo" in p.stdout + p.stderr:
        raise RuntimeError(f"mpv failed: {p.stdout}{p.stderr}")
    return dt


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--grids", default="640x320,1920x1080")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--calib", action="append", default=[], metavar="WxH=FILE")
    ap.add_argument("--variants", default=",".join(VARIANTS))
    args = ap.parse_args()
    given = dict(c.split("=", 1) for c in args.calib)
    out: dict[str, Any] = {
        "when": datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC"),
        "load_average": os.getloadavg()[0],
        "mpv": subprocess.run(["mpv", "--version"], capture_output=True, text=True).stdout.split(
            "\n"
        )[0],
        "grids": {},
    }
    with tempfile.TemporaryDirectory() as tmp_s, Xvfb((1920, 1080)):
        tmp = Path(tmp_s)
        for grid in args.grids.split(","):
            w, h = (int(v) for v in grid.split("x"))
            t0 = time.monotonic()
            cal = Calibration.load(given[grid]) if grid in given else small_calibration(w, h)
            clip = tmp / f"clip{grid}.mp4"
            write_clip(str(clip), [smooth_frame(w, h, seed=1)] * 5, 25, tone=False)
            res: dict[str, Any] = {"calibration_s": round(time.monotonic() - t0, 1)}
            for name in args.variants.split(","):
                t1 = time.monotonic()
                text, info = export_mpv_shader(cal, angle=60.0, **VARIANTS[name])
                shader = tmp / f"{grid}-{name}.glsl"
                if info.param:
                    text = without_param(text, 60.0)
                shader.write_text(text, encoding="ascii")
                export_s = time.monotonic() - t1
                with_s, without_s = [], []
                for _ in range(args.runs):  # in turn: the machine's load drifts
                    without_s.append(first_frame_s(clip, None))
                    with_s.append(first_frame_s(clip, shader))
                a, b = statistics.median(with_s), statistics.median(without_s)
                res[name] = {
                    "mb": round(len(text) / 1e6, 1),
                    "export_s": round(export_s, 2),
                    "first_frame_s": round(a, 2),
                    "without_shader_s": round(b, 2),
                    "load_s": round(a - b, 2),
                    "load_s_runs": [
                        round(x - y, 2) for x, y in zip(with_s, without_s, strict=True)
                    ],
                }
                shader.unlink()
                print(json.dumps({grid: {name: res[name]}}), flush=True)
            out["grids"][grid] = res
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
