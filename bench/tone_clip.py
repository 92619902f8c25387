"""Flicker of the tone maps in video: a 20-second clip with cuts, compensated frame by frame
as `render` does (numpy reference), what the eye sees of it measured frame by frame
(docs/EVALUATION.md "Adaptive tone map").

    .venv/bin/python bench/tone_clip.py [--size 128x64] [--fps 24] [--screen red]

The clip: four shots of 5 s (astronaut, coffee, chelsea, astronaut), each a slow pan across a
larger copy of the image. Per tone map (today's global rule and the adaptive field, both
smoothed with tau = 0.5 s as `render` smooths): the mean and largest change of the seen
image's mean luminance between consecutive frames inside a shot, the same for the ratio of
the seen image's mean luminance to the ideal's (the tone map's own part of it, the content's
own change taken out), and per cut the time after which that ratio changes by less than
0.5 % per frame for the rest of the shot.

The ratio still moves with the content where the map is not a uniform scale: a pan by whole
pixels moves the picture over the screen's uneven reach a row at a time, and the soft clip
follows it (``--hold``: every frame of a shot drawn with its first frame's parameters, so
that what moves the ratio is the content alone). So beside it the tone map's *own* change:
each frame seen under its own parameters against under the last frame's (the same content),
its mean and largest inside shots and the time after each cut from which it stays under
0.5 % per frame.

``--hold``: as ``render`` gets them, then each shot's first frame's held for the shot.

``--worker``: the parameters as ``play`` and the embedding API get them instead: the clip
is fed in real time (frame i at i / fps s) to a ``LiveRenderer`` (headless GL, its tone
worker at its defaults: 5 calls a second at most, a 32-pixel thumbnail, cuts told to it by
the frame thread), each frame's ``FrameRecord.params`` kept, then measured as above with the
numpy reference. Its settle after a cut includes the worker's latency on this machine.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace
from typing import Any

import cv2
import numpy as np

from viewcomp.calib.comp.compensation import Compensation, FrameParams, thumbnail
from viewcomp.calib.eval.adapted import SRGB
from viewcomp.calib.eval.testimages import natural_images
from viewcomp.calib.fit.calibrate import calibrate
from viewcomp.calib.io.captureset import capture_set_from_raw
from viewcomp.calib.model.gamut import LUMA
from viewcomp.calib.model.reference import compensate
from viewcomp.calib.sim.simulate import capture_patterns
from viewcomp.calib.sim.simulator import Simulator, make_screen, simulation_rig, white_screen

SHOTS = ("astronaut", "coffee", "chelsea", "astronaut")
SHOT_S = 5.0
STEADY = 0.005


def clip(w: int, h: int, fps: int) -> tuple[list[np.ndarray], list[int]]:
    """The frames and the index of each shot's first frame."""
    big = natural_images(2 * w, 2 * h)
    n = int(SHOT_S * fps)
    frames, starts = [], []
    for k, name in enumerate(SHOTS):
        starts.append(len(frames))
        src = cv2.resize(big[name], (int(1.5 * w), int(1.5 * h)), interpolation=cv2.INTER_AREA)
        for i in range(n):
            x = round((src.shape[1] - w) * i / (n - 1)) if k % 2 == 0 else 0
            y = 0 if k % 2 == 0 else round((src.shape[0] - h) * i / (n - 1))
            frames.append(np.ascontiguousarray(src[y : y + h, x : x + w]))
    return frames, starts


def luminance(img: np.ndarray) -> float:
    """Mean luminance of an 8-bit sRGB image, linear light."""
    return float(np.mean(SRGB.decode(img / 255.0) @ LUMA))


def render_params(
    cal: Any, frames: list[np.ndarray], eye: np.ndarray, tone: str, fps: int
) -> list[FrameParams]:
    """Each frame's parameters as ``render`` gets them (every frame, in order)."""
    comp = Compensation(cal, "pixel", tau=0.5, tone=tone)
    return [comp(thumbnail(f), eye, i / fps) for i, f in enumerate(frames)]


def worker_params(
    cal: Any, frames: list[np.ndarray], eye: np.ndarray, tone: str, fps: int
) -> list[FrameParams]:
    """Each frame's parameters as ``play`` gets them: a LiveRenderer fed in real time."""
    from viewcomp.rt.gl.context import create_context
    from viewcomp.rt.play.embed import LiveRenderer

    ctx = create_context()
    h, w = frames[0].shape[:2]
    fbo = ctx.simple_framebuffer((w, h))
    out = []
    start = tuple(float(x) for x in eye)
    with LiveRenderer(cal, ctx, eye=start, eye_tau=0.0, tone=tone, tone_tau=0.5) as live:
        t0 = time.monotonic()
        for i, f in enumerate(frames):
            time.sleep(max(0.0, t0 + i / fps - time.monotonic()))
            out.append(live.render(f, target=fbo, viewport=(0, 0, w, h)).params)
        late = time.monotonic() - t0 - (len(frames) - 1) / fps
    print(f"  ({tone}: fed in real time, the last frame {late:.2f} s late)", flush=True)
    return out


def measure(
    name: str, params: list[FrameParams], frames: list[np.ndarray], starts: list[int], fps: int,
    sim: Simulator, screen: Any, eye: np.ndarray, ideal: np.ndarray, sec: float,
) -> None:  # fmt: skip
    """Print the clip's figures (module docstring) for one list of per-frame parameters."""
    first = set(starts)
    seen, own = [], [0.0]
    for i, (f, p) in enumerate(zip(frames, params, strict=True)):
        out = compensate(p.model, f, eye, p.alpha, p.beta, field=p.field)
        seen.append(luminance(sim.observe(screen, out, eye)))
        if i:  # the same frame under the last frame's tone map
            q = params[i - 1]
            was = compensate(q.model, f, eye, q.alpha, q.beta, field=q.field)
            own.append(abs(seen[-1] / luminance(sim.observe(screen, was, eye)) - 1.0))
    lum, mine = np.array(seen), np.array(own)
    ratio = lum / ideal
    inside = np.array([i for i in range(1, len(frames)) if i not in first])
    d_lum = np.abs(lum[inside] / lum[inside - 1] - 1.0)
    d_ratio = np.abs(ratio[inside] / ratio[inside - 1] - 1.0)
    big = int(inside[np.argmax(mine[inside])])  # the tone map's largest step inside a shot
    cut_before = max(s for s in starts if s <= big)
    settle, settle_own = [], []
    for k, s in enumerate(starts[1:], 1):
        end = starts[k + 1] if k + 1 < len(starts) else len(frames)
        steps = np.abs(ratio[s + 1 : end] / ratio[s : end - 1] - 1.0)
        for moves, out_s in ((steps, settle), (mine[s + 1 : end], settle_own)):
            moving = np.nonzero(moves >= STEADY)[0]
            out_s.append(0.0 if moving.size == 0 else round(float(moving[-1] + 1) / fps, 3))
    print(
        f"{name}: seen mean-luminance change inside shots mean {100 * d_lum.mean():.3f} % "
        f"max {100 * d_lum.max():.3f} %; ideal's own mean "
        f"{100 * np.mean(np.abs(ideal[inside] / ideal[inside - 1] - 1)):.3f} %; "
        f"seen/ideal ratio change mean {100 * d_ratio.mean():.3f} % max "
        f"{100 * d_ratio.max():.3f} %; settled after each cut (s): {settle}; "
        f"the tone map's own change inside shots mean {100 * mine[inside].mean():.3f} % "
        f"max {100 * mine[inside].max():.3f} % ({(big - cut_before) / fps:.3f} s into its "
        f"shot), settled after each cut (s): {settle_own}; "
        f"{sec / len(frames) * 1000:.0f} ms per frame (choosing the parameters)",
        flush=True,
    )


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--size", default="128x64")
    ap.add_argument("--fps", type=int, default=24)
    ap.add_argument("--screen", default="red")
    ap.add_argument("--angle", type=float, default=60.0)
    ap.add_argument("--worker", action="store_true", help="the parameters as play gets them")
    ap.add_argument("--hold", action="store_true", help="each shot's first parameters held")
    args = ap.parse_args()
    w, h = (int(v) for v in args.size.split("x"))
    rig = simulation_rig()
    rig = replace(rig, projector=replace(rig.projector, resolution=(w, h), principal_point=None))
    sim = Simulator(rig=rig, seed=0)
    screen = make_screen(args.screen, "glossy", shape=sim.shape, seed=0)
    cal = calibrate(
        capture_set_from_raw(
            rig, capture_patterns(sim, white_screen()), capture_patterns(sim, screen)
        )
    )
    frames, starts = clip(w, h, args.fps)
    eye = rig.viewer.eye(args.angle)
    ideal = np.array([luminance(sim.observe(white_screen(), f, eye)) for f in frames])
    print(
        f"{len(frames)} frames ({len(frames) / args.fps:g} s, {args.fps} fps), cuts at "
        f"{[s / args.fps for s in starts[1:]]} s; {args.screen} glossy screen at "
        f"{args.angle:g} deg; parameters as {'play' if args.worker else 'render'} gets them"
        f"{', each shot held at its first' if args.hold else ''}"
    )
    get = worker_params if args.worker else render_params
    for tone in ("global", "adaptive"):
        t0 = time.perf_counter()
        params = get(cal, frames, eye, tone, args.fps)
        if args.hold:  # the content's own part: each shot at its first frame's parameters
            params = [params[max(s for s in starts if s <= i)] for i in range(len(frames))]
        sec = time.perf_counter() - t0
        measure(tone, params, frames, starts, args.fps, sim, screen, eye, ideal, sec)


if __name__ == "__main__":
    main()
