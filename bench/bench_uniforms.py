"""Literals and flat inputs vs a uniform block in the fragment shader: prints one JSON object.

The GL compensator compiles a model's numbers (the lobe's black share, the inverse LUT's position
constants) into its shader as ``#define`` literals and hands the frame's numbers (eye, tone
map, the paper method's folded rows) from the vertex shader as flat inputs. This measures,
in one process and on the same objects, the shipped shader against the same shader with

- ``ubo_frame``: the frame's numbers read from a uniform block (std140) in the fragment
  shader instead of the flat inputs;
- ``ubo_all``: those and the model's numbers from the block instead of the literals;

for the pixel method from the view cache (a held eye), solved per draw (a moving eye) and
the paper method, RGB input. Variants run in turn, ``--rounds`` times (the machine's load
drifts; each round's ratio compares draws made a moment apart). Per variant: the median
draw time (wall ms) over the rounds, the per-round medians and, against the literals, the
per-round ratios (median, min, max). The outputs must be equal (checked).

Run from the repository root::

    .venv/bin/python bench/bench_uniforms.py [--size 1920x1080] [--rounds 7] [--draws 7]
"""

from __future__ import annotations

import sys
from pathlib import Path

# The repository on sys.path: the synthetic models and calibrations are tests.support's.
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import argparse
import contextlib
import datetime
import json
import os
import statistics
import time
from collections.abc import Iterator
from typing import Any

import numpy as np

import viewcomp.rt.gl.compensator as compensator
from tests.support.synthetic import smooth_frame, synthetic_model
from viewcomp.calib.world.eye import eye_from_angle
from viewcomp.rt.gl.compensator import Compensator
from viewcomp.rt.gl.context import create_context, finish
from viewcomp.shaders import build_program, load

# The block: the frame's 4 vec4 (as v_frame), then the model's numbers.
_BLOCK = (
    "layout(std140) uniform Params { vec4 v_frame[4]; vec4 p_sq_scale, p_sq_off, p_sq_lo, "
    "p_sq_hi, p_lobe_black; };"
)
_MODEL = {"SQ_SCALE": 0, "SQ_OFF": 1, "SQ_LO": 2, "SQ_HI": 3, "LOBE_BLACK": 4}  # vec4 slot - 4


def _ubo_loader(name: str) -> str:
    text = load(name)
    if name == "compensate.frag.glsl":
        flat = "flat in vec4 v_frame[4];"
        if flat not in text:
            raise SystemExit(f"{name} no longer declares {flat!r}: update this benchmark")
        text = text.replace(flat, _BLOCK)
    return text


def _parse(literal: str) -> list[float]:
    inner = literal[literal.index("(") + 1 : -1] if "(" in literal else literal
    return [float(x) for x in inner.split(",")]


class _UboCompensator(Compensator):
    """The same Compensator with its fragment shader reading a uniform block."""

    def __init__(self, model: Any, ctx: Any, model_in_block: bool, **kw: Any) -> None:
        self._model_in_block = model_in_block
        super().__init__(model, ctx, **kw)
        self._block = np.zeros(4 * 4 + 5 * 4, np.float32)
        if model_in_block:
            for key, slot in _MODEL.items():
                if key in self._consts:
                    self._block[16 + 4 * slot : 16 + 4 * slot + 3] = _parse(str(self._consts[key]))
                    self._consts[key] = f"p_{key.lower()}.xyz"
        self._ubo = self._track(self.ctx.buffer(reserve=self._block.nbytes))

    def _program(self, method: int) -> tuple[Any, Any]:
        with _patched_build():
            prog, vao = super()._program(method)
        if "Params" in prog:
            prog["Params"].binding = 0
        return prog, vao

    def _render(self, method: int, flip_y: int) -> None:
        self._block[:16] = np.frombuffer(self._frame_values(), np.float32)
        self._ubo.write(self._block.tobytes())
        self._ubo.bind_to_uniform_block(0)
        super()._render(method, flip_y)


@contextlib.contextmanager
def _patched_build() -> Iterator[None]:
    """Compensator's programs compiled from the block-reading source for a moment."""
    original = compensator.build_program
    compensator.build_program = lambda ctx, defines=None: build_program(  # type: ignore[assignment]
        ctx, defines=defines, loader=_ubo_loader
    )
    try:
        yield
    finally:
        compensator.build_program = original  # type: ignore[assignment]


def _make(kind: str, method: str, cached: bool, ctx: Any, size: tuple[int, int]) -> Any:
    w, h = size
    model = synthetic_model(method, w, h)  # type: ignore[arg-type]
    kw = {"view_cache": cached, "view_hold": 0, "view_steps": 1}
    if kind == "literals":
        comp: Any = Compensator(model, ctx, **kw)
    else:
        comp = _UboCompensator(model, ctx, model_in_block=kind == "ubo_all", **kw)
    comp.set_eye(*eye_from_angle(60.0, 0.5, 0.035))
    comp.set_tone(0.55, 0.02)
    comp.upload(smooth_frame(w, h, seed=2))
    comp.draw()  # compiles (and builds the view cache)
    return comp


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="1920x1080")
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--draws", type=int, default=7, help="draws per variant and round")
    args = ap.parse_args(argv)
    size = tuple(int(x) for x in args.size.split("x"))
    ctx = create_context()
    report: dict[str, Any] = {
        "date": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
        "renderer": ctx.info["GL_RENDERER"],
        "size": args.size, "rounds": args.rounds, "draws": args.draws,
        "load_avg_start": [round(x, 2) for x in os.getloadavg()],
    }  # fmt: skip
    kinds = ("literals", "ubo_frame", "ubo_all")
    for name, method, cached in (
        ("pixel_cached", "pixel", True),
        ("pixel_solve", "pixel", False),
        ("paper", "paper", False),
    ):
        comps = {k: _make(k, method, cached, ctx, size) for k in kinds}  # type: ignore[arg-type]
        try:
            outs = {k: c.read() for k, c in comps.items()}
            same = all(np.array_equal(outs["literals"], o) for o in outs.values())
            paths = {k: c.last_path for k, c in comps.items()}
            times: dict[str, list[float]] = {k: [] for k in kinds}
            for r in range(args.rounds):
                order = kinds if r % 2 == 0 else kinds[::-1]
                for k in order:
                    c = comps[k]
                    ts = []
                    for _ in range(args.draws):
                        t = time.perf_counter()
                        c.draw()
                        finish(ctx)
                        ts.append(time.perf_counter() - t)
                    times[k].append(statistics.median(ts))
        finally:
            for c in comps.values():
                c.release()
        entry: dict[str, Any] = {"outputs_equal": same, "paths": paths}
        for k in kinds:
            e: dict[str, Any] = {
                "ms": round(1e3 * statistics.median(times[k]), 2),
                "ms_per_round": [round(1e3 * x, 2) for x in times[k]],
            }
            if k != "literals":
                ratios = [b / a for a, b in zip(times["literals"], times[k], strict=True)]
                e["over_literals"] = {
                    "median": round(statistics.median(ratios), 3),
                    "min": round(min(ratios), 3), "max": round(max(ratios), 3),
                }  # fmt: skip
            entry[k] = e
        report[name] = entry
        print(f"{name}: " + ", ".join(f"{k} {entry[k]['ms']} ms" for k in kinds), file=sys.stderr)
    report["load_avg_end"] = [round(x, 2) for x in os.getloadavg()]
    ctx.release()
    json.dump(report, sys.stdout, indent=1)
    print()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
