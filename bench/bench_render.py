"""Benchmark of the runtime: prints one JSON object to stdout (docs/BENCHMARKS.md).

Every entry is per frame, in milliseconds, as ``{"wall": .., "cpu": ..}``: the median wall
time and the median CPU time of the whole process (all threads: llvmpipe's rasterisers,
decoder, encoder). On a shared machine the wall time depends on who else runs; the CPU time
much less, so compare ratios within one run and look at both.

- ``per_frame``: at 720p, 1080p and 2160p: decode (PyAV on the worker thread, yuv420p planes
  out), upload (planes, RGB), the shader for ``identity`` (pass-through), ``pixel`` (float32
  maps, solved per frame: a moving eye), ``pixel_cached`` (drawn from the view cache: a held
  eye, what a constant ``--angle`` runs) and ``paper`` on planes and on RGB,
  ``view_cache_build_and_draw_rgb`` (a new eye: the whole cache rebuilt, then a draw),
  read-back; start-up (program compile, model upload) apart. The shaders evaluate
  ``shaders/compensate_core.glsl`` with the model's numbers compiled in as literals and the
  frame's from the vertex shader (``bench/bench_uniforms.py`` measures that against a
  uniform block).
- ``cpu_reference_1080p``: the numpy reference (``viewcomp.calib.model.reference.compensate``) and
  ``speedup_1080p`` = reference / GL (upload RGB + shader + read-back).
- ``params``: ``comp(thumb, eye, t)`` of ``viewcomp.calib.comp.compensation.Compensation`` on a
  real (simulated) calibration, the eye fixed or moving every frame, thumbnail included.
- ``pipeline_1080p``: the whole ``render_file`` (decode -> thumbnail -> params -> GL ->
  x264 CRF 18 preset veryfast on its own thread), marginal per frame = (time for 90 frames -
  time for 30 frames) / 60, so start-up is apart, repeated ``--pipeline-rounds`` times with
  the configurations in turn: identity; pixel with a fixed tone map (the GL pipeline alone);
  pixel with the real per-frame tone map at a constant angle (``viewcomp render --angle``)
  and with the eye moving every frame (``--track``). The clip: a 1080p pan over a
  procedural landscape (``viewcomp.calib.eval.testimages``), clean and with sensor-like grain.

Synthetic models (:mod:`tests.support.synthetic`) stand in for calibrations at 720p..2160p (the
GL cost depends on the grid, not on the numbers). Run from the repository root::

    .venv/bin/python bench/bench_render.py [--sizes 720p,1080p,2160p] [--repeats 5]
        [--pipeline-frames 30,90] [--pipeline-rounds 3] [--skip-pipeline | --pipeline-only]
        > bench.json
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
import platform
import statistics
import tempfile
import time
from collections.abc import Callable
from types import SimpleNamespace
from typing import Any

import av
import numpy as np

from tests.support.synthetic import SyntheticCompensation, smooth_frame, synthetic_model
from viewcomp.calib.model.reference import compensate
from viewcomp.rt.gl.compensator import Compensator, eye_from_angle
from viewcomp.rt.gl.context import create_context, finish
from viewcomp.rt.media.frames import rgb_to_yuv420p, yuv420p_to_rgb
from viewcomp.rt.media.video import VideoReader
from viewcomp.rt.render.pipeline import render_file
from viewcomp.rt.render.tracks import constant_angle

SIZES = {"720p": (1280, 720), "1080p": (1920, 1080), "2160p": (3840, 2160)}
EYE = eye_from_angle(60.0, 0.5, 0.035)
ALPHA, BETA = 0.55, 0.02


def _r(x: float) -> float:
    return round(1e3 * x, 2)


def _measure(fn: Callable[[], object], repeats: int) -> dict[str, float]:
    """Median wall and process-CPU milliseconds of ``fn`` over ``repeats`` (one warm-up)."""
    fn()
    wall, cpu = [], []
    for _ in range(repeats):
        t, c = time.perf_counter(), time.process_time()
        fn()
        wall.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
    return {"wall": _r(statistics.median(wall)), "cpu": _r(statistics.median(cpu))}


def _pan_frames(w: int, h: int, frames: int, grain: float) -> Callable[[int], np.ndarray]:
    """Frame i of a pan (4 px/frame) over a procedural landscape, with Gaussian grain."""
    from viewcomp.calib.eval.testimages import procedural_images

    base = procedural_images(w + 4 * frames, h)["landscape"]
    rng = np.random.default_rng(0)

    def frame(i: int) -> np.ndarray:
        f = base[:, 4 * i : 4 * i + w]
        if grain > 0:
            noise = rng.normal(0.0, grain, f.shape).astype(np.float32)
            f = np.clip(f + noise, 0, 255).astype(np.uint8)
        return np.ascontiguousarray(f)

    return frame


def _write_clip(path: Path, w: int, h: int, frames: int, grain: float = 0.0) -> None:
    """An H.264 clip (x264 ultrafast, CRF 18, 30 fps), no audio."""
    frame = _pan_frames(w, h, frames, grain)
    with av.open(str(path), "w") as out:
        vs = out.add_stream("libx264", rate=30)
        vs.width, vs.height, vs.pix_fmt = w, h, "yuv420p"
        vs.options = {"preset": "ultrafast", "crf": "18"}
        for i in range(frames):
            vf = av.VideoFrame.from_ndarray(frame(i), format="rgb24").reformat(format="yuv420p")
            vf.pts = i
            for packet in vs.encode(vf):
                out.mux(packet)
        for packet in vs.encode(None):
            out.mux(packet)


def _decode(path: Path) -> dict[str, float]:
    with VideoReader(path, audio="none") as reader:
        t, c = time.perf_counter(), time.process_time()
        n = sum(1 for _ in reader)
        return {"wall": _r((time.perf_counter() - t) / n), "cpu": _r((time.process_time() - c) / n)}


def bench_size(ctx: Any, name: str, repeats: int, tmp: Path) -> dict[str, Any]:
    w, h = SIZES[name]
    res: dict[str, Any] = {}
    clip = tmp / f"{name}.mp4"
    _write_clip(clip, w, h, frames=30)
    res["decode"] = _decode(clip)
    planes = rgb_to_yuv420p(smooth_frame(w, h, seed=2), "bt709")
    frame = yuv420p_to_rgb(planes)
    out = np.empty((h, w, 3), np.uint8)
    startup = {}
    # name, method, view cache: "pixel" solves per frame (a moving eye), "pixel_cached" draws
    # from the view cache (a held eye: the default for a constant angle).
    variants = (
        ("pixel", "pixel", False), ("pixel_cached", "pixel", True), ("paper", "paper", False),
    )  # fmt: skip
    for key, method, cached in variants:
        model = synthetic_model(method, w, h)  # type: ignore[arg-type]
        t = time.perf_counter()
        comp = Compensator(model, ctx, view_cache=cached, view_hold=0, view_steps=1)
        comp.set_eye(*EYE)
        comp.set_tone(ALPHA, BETA)
        comp.render_planes(planes, out=out)  # compiles the variant (and builds the cache)
        startup[key] = _r(time.perf_counter() - t)
        try:

            def draw(c: Compensator = comp) -> None:
                c.draw()
                finish(c.ctx)

            for kind in ("yuv", "rgb"):
                comp.upload_planes(planes) if kind == "yuv" else comp.upload(frame)
                res[f"{key}_{kind}"] = _measure(draw, repeats)
            if cached:
                state = {"i": 0}

                def rebuild(c: Compensator = comp, s: dict[str, int] = state) -> None:
                    s["i"] += 1  # a new eye each time: the whole cache is rebuilt
                    c.set_eye(*(EYE + np.float32(1e-4 * s["i"])))
                    c.draw()
                    finish(c.ctx)

                res["view_cache_build_and_draw_rgb"] = _measure(rebuild, repeats)
            if key == "pixel":
                res["upload_planes"] = _measure(
                    lambda c=comp: (c.upload_planes(planes), finish(c.ctx)), repeats
                )
                res["upload_rgb"] = _measure(
                    lambda c=comp: (c.upload(frame), finish(c.ctx)), repeats
                )
                res["readback"] = _measure(lambda c=comp: c.read(out), repeats)
                comp.identity = True
                t = time.perf_counter()
                comp.render_planes(planes, out=out)  # compile outside the timing
                startup["identity_program"] = _r(time.perf_counter() - t)
                for kind in ("yuv", "rgb"):
                    comp.upload_planes(planes) if kind == "yuv" else comp.upload(frame)
                    res[f"identity_{kind}"] = _measure(draw, repeats)
        finally:
            comp.release()
        del model
    res["startup_ms"] = startup
    return res


def bench_cpu_1080p(repeats: int) -> dict[str, Any]:
    w, h = SIZES["1080p"]
    frame = smooth_frame(w, h, seed=2)
    out = {}
    for method in ("pixel", "paper"):
        model = synthetic_model(method, w, h)  # type: ignore[arg-type]
        out[method] = _measure(lambda m=model: compensate(m, frame, EYE, ALPHA, BETA), repeats)
    return out


def bench_params(repeats: int, grid: tuple[int, int]) -> dict[str, Any]:
    """comp(thumb, eye, t) of the real Compensation, thumbnail of a 1080p frame included."""
    try:
        from tests.support.calibrations import small_calibration
        from viewcomp.calib.comp.compensation import THUMB_SIDE, Compensation
        from viewcomp.rt.media.frames import thumbnail_planes
    except ImportError as exc:
        return {"unavailable": str(exc)}
    cal = small_calibration(w=grid[0], h=grid[1])
    planes = rgb_to_yuv420p(_pan_frames(1920, 1080, 1, 0.0)(0), "bt709")
    res: dict[str, Any] = {"calibration_grid": f"{grid[0]}x{grid[1]}", "tau": 0.5}
    res["thumbnail_from_1080p_planes"] = _measure(
        lambda: thumbnail_planes(planes, THUMB_SIDE), repeats
    )
    thumb = thumbnail_planes(planes, THUMB_SIDE)
    res["thumbnail_shape"] = list(thumb.shape)
    for method in ("pixel", "paper"):
        comp = Compensation(cal, method, tau=0.5)
        comp.base_model()
        for moving in (False, True):
            state = {"i": 0}

            def call(c: Any = comp, mv: bool = moving, s: dict[str, int] = state) -> None:
                s["i"] += 1
                angle = 45.0 + (s["i"] % 90 if mv else 15)
                c(thumb, eye_from_angle(angle, 0.5, 0.035), s["i"] / 30)

            res[f"{method}_{'moving' if moving else 'fixed'}_eye"] = _measure(call, repeats)
    return res


def _real_tone_comp(model: Any) -> Any:
    """The real Compensation (per-frame tone map) on a synthetic 1080p pixel model."""
    from viewcomp.calib.comp.compensation import Compensation

    cal = SimpleNamespace(shape=model.shape, pixel=SimpleNamespace(runtime_model=lambda: model))
    return Compensation(cal, "pixel", tau=0.5)  # type: ignore[arg-type]


def _moving_eye(t: float) -> np.ndarray:
    """An eye sweeping 45..135 degrees and back every 6 s: a new eye every frame."""
    return eye_from_angle(90.0 + 45.0 * float(np.sin(2 * np.pi * t / 6.0)), 0.5, 0.035)


def bench_pipeline_1080p(
    ctx: Any, tmp: Path, counts: tuple[int, int], rounds: int
) -> dict[str, Any]:
    """Marginal per-frame cost of the whole render_file at 1080p, identity vs pixel.

    Configurations run in turn, ``rounds`` times over (the machine's load drifts; each
    round's ratio compares runs made seconds apart); per configuration the median over the
    rounds, and the median and range of the per-round ratios to identity.
    """
    w, h = SIZES["1080p"]
    model = synthetic_model("pixel", w, h)
    fixed = SyntheticCompensation(model, (ALPHA, BETA))
    held = constant_angle(60, 0.5, 0.035)
    try:
        real: Any = _real_tone_comp(model)
    except Exception as exc:  # a synthetic model that Compensation does not accept
        real = None
        real_error = f"{type(exc).__name__}: {exc}"
    res: dict[str, Any] = {
        "frames": list(counts), "rounds": rounds, "encoder": "libx264 crf 18 veryfast",
    }  # fmt: skip
    # name: (comp, identity, eye track); the real tone map is what `viewcomp render` runs.
    configs: dict[str, tuple[Any, bool, Any]] = {
        "identity": (fixed, True, held),
        "pixel_fixed_tone": (fixed, False, held),
    }
    if real is not None:
        configs["pixel_real_tone"] = (real, False, held)
        configs["pixel_real_tone_moving_eye"] = (real, False, _moving_eye)
    for grain in (0.0, 2.0):
        label = "clean" if grain == 0 else "grain"
        clips = {n: tmp / f"pipe_{label}_{n}.mp4" for n in counts}
        for n, path in clips.items():
            _write_clip(path, w, h, frames=n, grain=grain)
        per_round: dict[str, list[dict[str, Any]]] = {name: [] for name in configs}
        for _ in range(rounds):
            for name, (comp, identity, track) in configs.items():
                runs = {}
                for n, path in clips.items():
                    if hasattr(comp, "smoother") and comp.smoother is not None:
                        comp.smoother.state = None  # each run starts afresh
                    t, c = time.perf_counter(), time.process_time()
                    stats = render_file(comp, path, tmp / "out.mp4", track, identity=identity,
                                        progress=False, ctx=ctx)  # fmt: skip
                    runs[n] = (time.perf_counter() - t, time.process_time() - c, stats)
                (a_wall, a_cpu, a), (b_wall, b_cpu, b) = runs[counts[0]], runs[counts[1]]
                dn = b.frames - a.frames
                per_round[name].append({
                    "wall": (b_wall - a_wall) / dn, "cpu": (b_cpu - a_cpu) / dn,
                    "params": (b.params_seconds - a.params_seconds) / dn,
                    "startup": a.startup_seconds,
                })  # fmt: skip
        out: dict[str, Any] = {}
        ident = per_round["identity"]
        for name, rows in per_round.items():
            wall = statistics.median(r["wall"] for r in rows)
            entry: dict[str, Any] = {
                "fps": round(1.0 / wall, 2),
                "ms": {"wall": _r(wall), "cpu": _r(statistics.median(r["cpu"] for r in rows))},
                "ms_wall_per_round": [_r(r["wall"]) for r in rows],
                "params_ms": _r(statistics.median(r["params"] for r in rows)),
                "startup_s": round(statistics.median(r["startup"] for r in rows), 2),
            }
            if name != "identity":
                # fps / identity fps = identity's per-frame time / this one's, per round.
                ratios = [i["wall"] / r["wall"] for i, r in zip(ident, rows, strict=True)]
                cpu = [i["cpu"] / r["cpu"] for i, r in zip(ident, rows, strict=True)]
                entry["fps_over_identity"] = {
                    "median": round(statistics.median(ratios), 3),
                    "min": round(min(ratios), 3), "max": round(max(ratios), 3),
                    "cpu_median": round(statistics.median(cpu), 3),
                }  # fmt: skip
            out[name] = entry
        res[label] = out
    if real is None:
        res["pixel_real_tone"] = f"unavailable: {real_error}"
    return res


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="720p,1080p,2160p")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--pipeline-frames", default="30,90")
    ap.add_argument("--params-grid", default="320x160", help="calibration grid for params")
    ap.add_argument("--pipeline-rounds", type=int, default=3, help="pipeline repetitions")
    ap.add_argument("--skip-pipeline", action="store_true")
    ap.add_argument(
        "--pipeline-only", action="store_true", help="only pipeline_1080p (no per-frame parts)"
    )
    args = ap.parse_args(argv)
    if args.skip_pipeline and args.pipeline_only:
        ap.error("--skip-pipeline and --pipeline-only exclude each other")
    counts = tuple(int(x) for x in args.pipeline_frames.split(","))
    t = time.perf_counter()
    ctx = create_context()
    report: dict[str, Any] = {
        "date": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
        "machine": {
            "cpus": os.cpu_count(),
            "cpu": platform.processor() or platform.machine(),
            "renderer": ctx.info["GL_RENDERER"],
            "gl_version": ctx.info["GL_VERSION"],
            "python": platform.python_version(),
            "load_avg_start": [round(x, 2) for x in os.getloadavg()],
        },
        "context_ms": _r(time.perf_counter() - t),
    }
    with tempfile.TemporaryDirectory() as tmpdir:
        tmp = Path(tmpdir)
        sizes = [] if args.pipeline_only else args.sizes.split(",")
        report["per_frame"] = {n: bench_size(ctx, n, args.repeats, tmp) for n in sizes}
        if not args.pipeline_only:
            report["cpu_reference_1080p"] = bench_cpu_1080p(max(2, args.repeats // 2))
        gl = report["per_frame"].get("1080p")
        if gl is not None:
            cpu = report["cpu_reference_1080p"]

            def per_frame(m: str, k: str) -> float:
                return gl["upload_rgb"][k] + gl[f"{m}_rgb"][k] + gl["readback"][k]

            report["speedup_1080p"] = {
                m: {k: round(cpu[m][k] / per_frame(m, k), 1) for k in ("wall", "cpu")}
                for m in ("pixel", "paper")
            }
        if not args.pipeline_only:
            gw, gh = (int(x) for x in args.params_grid.split("x"))
            report["params"] = bench_params(max(3, args.repeats), (gw, gh))
        if not args.skip_pipeline:
            report["pipeline_1080p"] = bench_pipeline_1080p(
                ctx,
                tmp,
                counts,
                args.pipeline_rounds,  # type: ignore[arg-type]
            )
    report["machine"]["load_avg_end"] = [round(x, 2) for x in os.getloadavg()]
    ctx.release()
    json.dump(report, sys.stdout, indent=1)
    print()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
