"""Benchmark of the runtime: prints one JSON object to stdout.

Per-frame milliseconds (median of the repeats) at 720p, 1080p and 2160p for: decode (PyAV on
the worker thread, yuv420p planes out), upload (three planes), compensation draw (``pixel``,
``paper``), pass-through draw (``identity``), read-back; the numpy reference at 1080p;
start-up (context, shader compile, model upload) apart; and at 1080p the whole
``render_file`` pipeline (decode -> compensate -> x264 encode) with and without compensation.

Synthetic models from :mod:`viewcomp.rt.testing`; run as
``.venv/bin/python bench/bench_render.py [--sizes 720p,1080p] [--repeats 7]``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import av
import numpy as np

from viewcomp.calib.reference import compensate
from viewcomp.rt.compensator import Compensator, eye_from_angle
from viewcomp.rt.context import create_context
from viewcomp.rt.frames import rgb_to_yuv420p, yuv420p_to_rgb
from viewcomp.rt.pipeline import render_file
from viewcomp.rt.testing import smooth_frame, synthetic_model
from viewcomp.rt.tracks import constant_angle
from viewcomp.rt.video import VideoReader

SIZES = {"720p": (1280, 720), "1080p": (1920, 1080), "2160p": (3840, 2160)}
EYE = eye_from_angle(60.0, 0.5, 0.035)


def _ms(fn: Callable[[], object], repeats: int) -> float:
    """Median wall milliseconds of ``fn`` over ``repeats`` runs (after one warm-up run)."""
    fn()
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return round(1e3 * statistics.median(times), 2)


def _write_clip(path: Path, w: int, h: int, frames: int, rate: int = 30) -> None:
    """An H.264 clip (ultrafast) of a smooth image scrolling, no audio."""
    planes = rgb_to_yuv420p(smooth_frame(w, h, seed=1), "bt709")
    with av.open(str(path), "w") as out:
        vs = out.add_stream("libx264", rate=rate)
        vs.width, vs.height, vs.pix_fmt = w, h, "yuv420p"
        vs.options = {"preset": "ultrafast", "crf": "20"}
        for i in range(frames):
            frame = av.VideoFrame(w, h, "yuv420p")
            for plane, arr in zip(frame.planes, (planes.y, planes.u, planes.v), strict=True):
                view = np.frombuffer(plane, np.uint8).reshape(plane.height, plane.line_size)
                view[:, : plane.width] = np.roll(arr, 4 * i // (1 + (arr is not planes.y)), 1)
            frame.pts = i
            for packet in vs.encode(frame):
                out.mux(packet)
        for packet in vs.encode(None):
            out.mux(packet)


def _decode_ms(path: Path) -> float:
    with VideoReader(path, audio="none") as reader:
        t = time.perf_counter()
        n = sum(1 for _ in reader)
        return round(1e3 * (time.perf_counter() - t) / n, 2)


def bench_size(ctx: object, name: str, repeats: int, tmp: Path) -> dict[str, object]:
    w, h = SIZES[name]
    res: dict[str, object] = {}
    clip = tmp / f"{name}.mp4"
    _write_clip(clip, w, h, frames=12)
    res["decode_ms"] = _decode_ms(clip)
    planes = rgb_to_yuv420p(smooth_frame(w, h, seed=2), "bt709")
    frame = yuv420p_to_rgb(planes)
    startup = {}
    for method in ("pixel", "paper"):
        model = synthetic_model(method, w, h)
        t = time.perf_counter()
        comp = Compensator(model, ctx)  # type: ignore[arg-type]
        comp.set_eye(*EYE)
        comp.set_tone(0.55, 0.02)
        comp.render_planes(planes)  # compiles the variant, first draw
        ctx.finish()  # type: ignore[attr-defined]
        startup[f"{method}_ms"] = round(1e3 * (time.perf_counter() - t), 1)
        try:

            def draw(c: Compensator = comp) -> None:
                c.draw()
                c.ctx.finish()

            comp.upload_planes(planes)
            res[f"{method}_ms"] = _ms(draw, repeats)
            if method == "pixel":
                res["upload_planes_ms"] = _ms(
                    lambda c=comp: (c.upload_planes(planes), c.ctx.finish()), repeats
                )
                res["upload_rgb_ms"] = _ms(
                    lambda c=comp: (c.upload(frame), c.ctx.finish()), repeats
                )
                res["readback_ms"] = _ms(comp.read, repeats)
                comp.identity = True
                comp.upload_planes(planes)
                res["identity_yuv_ms"] = _ms(draw, repeats)
                comp.upload(frame)
                res["identity_rgb_ms"] = _ms(draw, repeats)
        finally:
            comp.release()
        del model
    res["startup_ms"] = startup
    return res


def bench_cpu_1080p(repeats: int) -> dict[str, float]:
    w, h = SIZES["1080p"]
    frame = smooth_frame(w, h, seed=2)
    out = {}
    for method in ("pixel", "paper"):
        model = synthetic_model(method, w, h)
        out[f"{method}_ms"] = _ms(lambda m=model: compensate(m, frame, EYE, 0.55, 0.02), repeats)
    return out


def bench_pipeline_1080p(ctx: object, tmp: Path, frames: int) -> dict[str, float]:
    """Whole render_file (decode -> GL -> x264 CRF 18) fps at 1080p, identity vs pixel."""
    w, h = SIZES["1080p"]
    clip = tmp / "pipe.mp4"
    _write_clip(clip, w, h, frames=frames)
    model = synthetic_model("pixel", w, h)
    out = {}
    for label, identity in (("identity_fps", True), ("pixel_fps", False)):
        stats = render_file(model, clip, tmp / f"out_{label}.mp4", constant_angle(60, 0.5, 0.035),
                            identity=identity, progress=False, tone=lambda t: (0.55, 0.02),
                            ctx=ctx)  # fmt: skip
        out[label] = round(stats.fps, 2)
    out["pixel_over_identity"] = round(out["pixel_fps"] / out["identity_fps"], 3)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="720p,1080p,2160p")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--pipeline-frames", type=int, default=30)
    args = ap.parse_args(argv)
    t = time.perf_counter()
    ctx = create_context()
    report: dict[str, object] = {
        "renderer": ctx.info["GL_RENDERER"],
        "cpus": os.cpu_count(),
        "load_avg_1min": round(os.getloadavg()[0], 2),
        "context_ms": round(1e3 * (time.perf_counter() - t), 1),
    }
    with tempfile.TemporaryDirectory() as tmpdir:
        tmp = Path(tmpdir)
        for name in args.sizes.split(","):
            report[name] = bench_size(ctx, name, args.repeats, tmp)
        report["cpu_reference_1080p"] = bench_cpu_1080p(max(2, args.repeats // 2))
        if "1080p" in report:
            gl = report["1080p"]
            cpu = report["cpu_reference_1080p"]
            assert isinstance(gl, dict)
            report["speedup_1080p"] = {
                m: round(cpu[f"{m}_ms"] / gl[f"{m}_ms"], 1) for m in ("pixel", "paper")
            }
            report["pipeline_1080p"] = bench_pipeline_1080p(ctx, tmp, args.pipeline_frames)
    ctx.release()
    json.dump(report, sys.stdout, indent=2)
    print()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
