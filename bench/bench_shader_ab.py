"""Another compensate.frag.glsl against the package's, in one process: prints one JSON object.

For a shader change, the fairest timing on a shared machine: the same Compensator objects'
data, the two shader texts compiled side by side, their draws alternating within rounds
(so that the machine's drift hits both alike). ``--other`` is the other text, e.g. the one
of an earlier commit::

    git show 37fb91d:shaders/compensate.frag.glsl > old.glsl
    .venv/bin/python bench/bench_shader_ab.py --other old.glsl --define PACKED=0 \\
        --define MAP_N=8 > ab.json

(``--define``: extra ``#define`` values that the other text needs and the current
Compensator no longer passes; ``--other-core``: the other compensate_core.glsl too, when the
formula itself changed.) Per draw variant (identity, pixel solved, pixel from the view
cache, paper; RGB and yuv420p input) at ``--size``: the median draw time (wall ms) of each
over the rounds, the median, min and max of the per-round ratio package / other, and
whether the outputs are bit-identical.
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
from typing import Any

import numpy as np

import viewcomp.rt.gl.shader_passes as compensator
from tests.support.synthetic import smooth_frame, synthetic_model
from viewcomp.calib.world.eye import eye_from_angle
from viewcomp.rt.gl.compensator import Compensator
from viewcomp.rt.gl.context import create_context, finish
from viewcomp.rt.media.frames import rgb_to_yuv420p
from viewcomp.shaders import build_program, load


def _other_class(text: str, extra: dict[str, str], core: str | None = None) -> type[Compensator]:
    def loader(name: str) -> str:
        if name == "compensate.frag.glsl":
            return text
        if name == "compensate_core.glsl" and core is not None:
            return core
        return load(name)

    class Other(Compensator):
        """Compensator whose programs compile ``text`` as compensate.frag.glsl."""

        def _program(self, method: int) -> tuple[Any, Any]:
            original = compensator.build_program
            compensator.build_program = lambda ctx, defines=None: build_program(  # type: ignore[assignment]
                ctx, defines={**(defines or {}), **extra}, loader=loader
            )
            try:
                return super()._program(method)
            finally:
                compensator.build_program = original  # type: ignore[assignment]

    return Other


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--other", required=True, help="the other compensate.frag.glsl")
    ap.add_argument("--define", action="append", default=[], help="KEY=VALUE for the other")
    ap.add_argument(
        "--other-core",
        default=None,
        help="the other compensate_core.glsl, for a change of the formula itself (the outputs "
        "then differ; the timing compares the two formulas on the same data)",
    )
    ap.add_argument("--size", default="1920x1080")
    ap.add_argument("--rounds", type=int, default=11)
    ap.add_argument("--draws", type=int, default=7, help="draws per shader and round")
    args = ap.parse_args(argv)
    w, h = (int(x) for x in args.size.split("x"))
    extra = dict(d.split("=", 1) for d in args.define)
    core = Path(args.other_core).read_text(encoding="utf-8") if args.other_core else None
    other = _other_class(Path(args.other).read_text(encoding="utf-8"), extra, core)
    ctx = create_context()
    report: dict[str, Any] = {
        "date": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
        "renderer": ctx.info["GL_RENDERER"], "size": args.size, "other": args.other,
        "rounds": args.rounds, "draws": args.draws,
        "load_avg_start": [round(x, 2) for x in os.getloadavg()],
    }  # fmt: skip
    frame = smooth_frame(w, h, seed=2)
    planes = rgb_to_yuv420p(frame, "bt709")
    variants = (
        ("identity", "pixel", False, True), ("pixel_solve", "pixel", False, False),
        ("pixel_cached", "pixel", True, False), ("paper", "paper", False, False),
    )  # fmt: skip
    for name, method, cached, identity in variants:
        comps = {}
        for key, cls in (("other", other), ("package", Compensator)):
            c = cls(synthetic_model(method, w, h), ctx, view_cache=cached, view_hold=0,  # type: ignore[arg-type]
                    view_steps=1)  # fmt: skip
            c.set_eye(*eye_from_angle(60.0, 0.5, 0.035))
            c.set_tone(0.55, 0.02)
            c.identity = identity
            comps[key] = c
        try:
            for inp in ("rgb", "yuv"):
                outs = {}
                for key, c in comps.items():
                    c.upload(frame) if inp == "rgb" else c.upload_planes(planes)
                    c.draw()  # compiles (and builds the view cache)
                    outs[key] = c.read()
                times: dict[str, list[float]] = {"other": [], "package": []}
                for r in range(args.rounds):
                    for key in ("other", "package") if r % 2 == 0 else ("package", "other"):
                        ts = []
                        for _ in range(args.draws):
                            t = time.perf_counter()
                            comps[key].draw()
                            finish(ctx)
                            ts.append(time.perf_counter() - t)
                        times[key].append(statistics.median(ts))
                ratios = [p / o for o, p in zip(times["other"], times["package"], strict=True)]
                report[f"{name}_{inp}"] = entry = {
                    "other_ms": round(1e3 * statistics.median(times["other"]), 2),
                    "package_ms": round(1e3 * statistics.median(times["package"]), 2),
                    "package_over_other": {
                        "median": round(statistics.median(ratios), 3),
                        "min": round(min(ratios), 3), "max": round(max(ratios), 3),
                    },
                    "outputs_identical": bool(np.array_equal(outs["other"], outs["package"])),
                    "path": comps["package"].last_path,
                }  # fmt: skip
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
