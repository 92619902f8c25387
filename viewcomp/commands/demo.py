"""`viewcomp demo`: the main job end to end on a built-in example, no arguments needed."""

from __future__ import annotations

import argparse
from pathlib import Path

from viewcomp.commands._common import add_simulator_arguments

DEMO_ANGLES = (45, 60, 90, 120, 135)
WALK_CSV = "# seconds,degrees: the viewer walks 60 -> 120 -> 60\n0,60\n2,120\n4,60\n"


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "demo",
        help="simulate, calibrate and compensate a built-in example; write a picture",
        description="End to end without hardware: a simulated glossy magenta screen is "
        "captured and calibrated, natural images are compensated for several viewing angles "
        "with both methods, and what a viewer would see at each angle is written side by "
        "side (ideal white screen | uncompensated | paper | per-pixel). Then a short clip is "
        "compensated with the GLSL shader while the viewer walks from 60 to 120 degrees and "
        "back, and what that viewer sees is written as a video.",
    )
    p.add_argument("--out", default="viewcomp-demo", help="output folder (default ./viewcomp-demo)")
    add_simulator_arguments(p, gloss=False, size=None)
    p.add_argument("--no-video", action="store_true", help="only the still pictures")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    import cv2
    import numpy as np

    from viewcomp.calib.comp.compensation import Compensation
    from viewcomp.calib.eval.metrics import delta_e2000
    from viewcomp.calib.eval.preview import band, labelled_row
    from viewcomp.calib.eval.testimages import natural_images
    from viewcomp.calib.fit.calibrate import Calibration, calibrate
    from viewcomp.calib.io.captureset import read_capture_set
    from viewcomp.calib.io.imageio import write_png
    from viewcomp.calib.sim.simulate import simulate_capture_set
    from viewcomp.calib.sim.simulator import Simulator, make_screen, simulation_rig, white_screen
    from viewcomp.commands._common import Log, check_output_folder, simulated_screen

    check_output_folder(args.out)
    log = Log()
    out = Path(args.out)
    caps = out / "captures"
    colour = simulated_screen(args)[0]
    name = colour if isinstance(colour, str) else args.screen
    log(f"simulating a glossy {name} screen: capture set in {caps}")
    simulate_capture_set(caps, colour, "glossy", seed=args.seed)
    log("calibrating both methods")
    cal = calibrate(read_capture_set(caps))
    bundle = out / f"{colour if isinstance(colour, str) else 'screen'}.vcb"
    cal.save(bundle)
    cal = Calibration.load(bundle)
    log(f"wrote the calibration bundle {bundle}")

    sim = Simulator(rig=simulation_rig(), seed=args.seed)
    screen = make_screen(colour, "glossy", shape=sim.shape, seed=args.seed)
    h, w = sim.shape
    images = dict(list(natural_images(w, h).items())[:2])
    comps = {m: Compensation(cal, m) for m in ("paper", "pixel")}
    rows, table = [], []
    for iname, image in images.items():
        for angle in DEMO_ANGLES:
            eye = cal.eye(angle)
            ideal = sim.observe(white_screen(), image, eye)
            tiles = {
                "white screen (ideal)": ideal,
                "uncompensated": sim.observe(screen, image, eye),
            }
            for m, comp in comps.items():
                img, _ = comp.compensate_image(image, eye)
                tiles[f"{m} method"] = sim.observe(screen, img, eye)
            de = {k: delta_e2000(v, ideal) for k, v in tiles.items()}
            table.append((iname, angle, de))
            small = [
                cv2.resize(v, (w // 2, h // 2), interpolation=cv2.INTER_AREA)
                for v in tiles.values()
            ]
            heads = [
                [k, f"seen at {angle} deg" if k.startswith("white") else f"dE {de[k]:.1f}"]
                for k in tiles
            ]
            rows.append(labelled_row(small, heads))
        log(f"compensated {iname} for angles {', '.join(map(str, DEMO_ANGLES))}")
    body = np.concatenate(rows, axis=0)
    title = (
        f"what a viewer sees on the simulated glossy {name} screen at each angle "
        "(dE: mean CIEDE2000 vs the white screen, lower is better)"
    )
    grid = np.concatenate([band(body.shape[1], [title]), body], axis=0)
    picture = out / "demo.png"
    write_png(picture, grid)
    print("\nmean CIEDE2000 against the white screen (lower is better):")
    print(f"{'image':>10} {'angle':>5} {'uncompensated':>14} {'paper':>7} {'per-pixel':>9}")
    for iname, angle, de in table:
        print(
            f"{iname:>10} {angle:>5} {de['uncompensated']:>14.2f} {de['paper method']:>7.2f} "
            f"{de['pixel method']:>9.2f}"
        )
    print(f"\nside-by-side picture (what a viewer sees at each angle): {picture.resolve()}")
    if not args.no_video:
        _video(out, cal, sim, screen, images, log)
    else:
        _remove_old_videos(out, log)
    return 0


def _remove_old_videos(out: Path, log) -> None:
    """A demo folder holds one run: videos of an earlier run would not match this picture."""
    for old in VIDEO_OUTPUTS:
        if (out / old).is_file():
            (out / old).unlink()
            log(f"removed {out / old} of an earlier run (--no-video)")


#: The files the video part of the demo writes into its folder.
VIDEO_OUTPUTS = ("clip.mp4", "walk.csv", "clip-compensated.mp4", "viewer.mp4")


def _video(out: Path, cal, sim, screen, images: dict, log) -> None:
    """Compensate a clip with the shader for a walking viewer; write what the viewer sees."""
    from viewcomp.calib.comp.compensation import Compensation
    from viewcomp.calib.eval.preview import labelled_row
    from viewcomp.calib.io.atomic import write_text_atomic
    from viewcomp.calib.sim.simulator import white_screen
    from viewcomp.calib.world.eye import eye_to_polar
    from viewcomp.rt.gl.context import GLUnavailable
    from viewcomp.rt.render.pipeline import render_file
    from viewcomp.rt.render.tracks import load_angle_track

    clip, track_csv = out / "clip.mp4", out / "walk.csv"
    write_pan_clip(clip, list(images.values()), seconds=4.0, rate=25)
    write_text_atomic(track_csv, WALK_CSV)
    v = cal.rig.viewer
    track = load_angle_track(track_csv, v.distance, v.height)
    comp_clip = out / "clip-compensated.mp4"
    comp = Compensation(cal, "pixel", tau=0.5)
    try:
        stats = render_file(comp, clip, comp_clip, track, backend="gl", progress=False)
        backend = "GLSL shader (EGL)"
    except GLUnavailable as e:
        log(f"no OpenGL ({e}); rendering with the numpy reference instead")
        stats = render_file(comp, clip, comp_clip, track, backend="cpu", progress=False)
        backend = "numpy reference"
    log(f"compensated {stats.frames} frames with the {backend}: {comp_clip}")
    frames_in, times = _read_clip(clip)
    frames_out, _ = _read_clip(comp_clip)
    tiles = []
    for t, a, b in zip(times, frames_in, frames_out, strict=False):
        eye = track(t)
        angle = eye_to_polar(eye)[0]
        row = [
            sim.observe(white_screen(), a, eye),
            sim.observe(screen, a, eye),
            sim.observe(screen, b, eye),
        ]
        heads = [
            ["white screen (ideal)", f"viewer at {angle:.0f} deg, {t:.1f} s"],
            ["uncompensated", ""],
            ["compensated (GLSL, per-pixel)", ""],
        ]
        tiles.append(labelled_row(row, heads))
    viewer = out / "viewer.mp4"
    _write_frames(viewer, tiles, 25)
    log(f"what the walking viewer sees (white screen | uncompensated | compensated): {viewer}")
    print(f"video: {viewer.resolve()}")


def write_pan_clip(path: Path, images: list, seconds: float, rate: int) -> None:
    """A slow pan across the images with a 440 Hz tone (the demo's input clip; also
    examples/make_inputs.py's), written atomically."""
    import numpy as np

    n = round(seconds * rate)
    w = images[0].shape[1]
    strip = np.concatenate(images, axis=1)
    span = strip.shape[1] - w
    frames = [strip[:, round(span * i / max(n - 1, 1)) :][:, :w] for i in range(n)]
    from viewcomp.calib.io.atomic import atomic_path
    from viewcomp.rt.media.sample_clip import write_clip

    with atomic_path(path) as tmp:
        write_clip(str(tmp), frames, rate, options={"preset": "veryfast", "crf": "18"})


def _write_frames(path: Path, frames: list, rate: int) -> None:
    """What the viewer sees, through the product's video writer (atomic, tagged BT.709)."""
    from fractions import Fraction

    from viewcomp.rt.media.video import VideoWriter

    h, w = frames[0].shape[:2]
    h, w = h - h % 2, w - w % 2
    with VideoWriter(path, w, h, Fraction(rate)) as writer:
        for f in frames:
            writer.write(f[:h, :w])


def _read_clip(path: Path) -> tuple[list, list]:
    import av

    frames, times = [], []
    with av.open(str(path)) as c:
        for f in c.decode(video=0):
            frames.append(f.to_ndarray(format="rgb24"))
            times.append(float(f.time or 0.0))
    return frames, times
