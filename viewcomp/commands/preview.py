"""`viewcomp preview CALIB INPUT -o OUT.png`: what the audience will see, predicted."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from viewcomp.commands._common import add_eye_arguments, add_tone_arguments, parse_vec3

if TYPE_CHECKING:
    from viewcomp.calib.fit.calibrate import Calibration


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "preview",
        help="predict what a viewer at an angle sees on the calibrated screen (PNG)",
        description="Predict, with the calibration's own model, what a viewer at the given "
        "angle or eye position sees on the calibrated screen, and write it side by side with "
        "what the white screen would show and with the uncompensated projection, labelled, "
        "with each one's colour error against the white screen (mean CIEDE2000). A fourth "
        "column shows what the projector itself shows. For a video, a contact sheet: one row "
        "per sampled frame (each compensated as a still). With --audience, the picture is "
        "compensated for all the viewers at once and there is one row per viewer: what each "
        "of them sees of it.",
    )
    p.add_argument("calib", help="calibration bundle from `viewcomp calibrate`")
    p.add_argument("input", help="image (.png, .jpg, ...) or video (anything FFmpeg reads)")
    p.add_argument("-o", "--output", required=True, help="the picture to write (.png)")
    add_eye_arguments(p, required=True, audience=True)
    add_tone_arguments(p, smooth=False)
    p.add_argument(
        "--frames",
        type=int,
        default=4,
        metavar="N",
        help="video: rows of the contact sheet, evenly spaced (default 4)",
    )
    p.add_argument(
        "--reach",
        metavar="PNG",
        help="also write the per-pixel reach at the eye (each viewer of --audience: one row "
        "each) to this picture: the highest and lowest colour each projector pixel can produce "
        "on the surface, beside the white screen at full output",
    )
    p.set_defaults(run=run)


def _video_frames(path: Path, grid: tuple[int, int], n: int) -> list[tuple[float, object]]:
    """``n`` frames evenly spaced over the video, fitted to ``grid`` (W, H): (time, RGB)."""
    from viewcomp.rt.media.frames import Planes, yuv420p_to_rgb
    from viewcomp.rt.media.video import VideoReader

    with VideoReader(path, fit=grid, audio="none") as reader:
        duration = reader.info.duration
        frames = reader.info.frames
        planes = []
        for item in reader:
            if isinstance(item, Planes):
                planes.append(item)
                if frames is None and duration is None and len(planes) > 10_000:
                    break
    if not planes:
        return []
    idx = sorted({round(i * (len(planes) - 1) / max(n - 1, 1)) for i in range(n)})
    return [(planes[i].time, yuv420p_to_rgb(planes[i])) for i in idx]


def _write_reach(cal: Calibration, eyes: list, path: Path) -> None:
    """The per-pixel reach picture at each eye (calib/eval/reach_picture.py)."""
    import numpy as np

    from viewcomp.calib.eval.reach_picture import reach_picture
    from viewcomp.calib.io.imageio import write_png
    from viewcomp.calib.world.eye import eye_to_polar

    rows = [(f"seen at {eye_to_polar(e)[0]:.0f} deg", np.asarray(e, np.float64)) for e in eyes]
    title = "per-pixel reach: the highest and lowest colour each projector pixel can produce"
    write_png(path, reach_picture(cal, rows, title))
    print(f"wrote {path}: the per-pixel reach at {len(rows)} eye(s)")


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from viewcomp.calib.comp.compensation import Compensation
    from viewcomp.calib.comp.tonemap import DEFAULT_LAMBDA
    from viewcomp.calib.errors import UsageError
    from viewcomp.calib.eval.preview import METHOD_NAMES, predict, preview_picture
    from viewcomp.calib.fit.calibrate import Calibration
    from viewcomp.calib.io.imageio import read_rgb8, write_png
    from viewcomp.calib.world.eye import eye_to_polar
    from viewcomp.rt.media.frames import fit_rgb
    from viewcomp.rt.render.pipeline import is_image

    src, out = Path(args.input), Path(args.output)
    if out.suffix.lower() != ".png":
        raise UsageError(f"the preview is a picture: give -o a .png file, got {out}")
    if out.resolve() == src.resolve() or out.resolve() == Path(args.calib).resolve():
        raise UsageError(f"-o {out} would overwrite an input; give another file name")
    if args.frames < 1:
        raise UsageError(f"--frames is at least 1, got {args.frames}")
    reach_out = Path(args.reach) if args.reach is not None else None
    if reach_out is not None:
        if reach_out.suffix.lower() != ".png":
            raise UsageError(f"the reach is a picture: give --reach a .png file, got {reach_out}")
        if reach_out.resolve() in (out.resolve(), src.resolve(), Path(args.calib).resolve()):
            raise UsageError(f"--reach {reach_out} would overwrite another file; give another name")
    cal = Calibration.load(args.calib)
    audience = None
    if args.audience is not None:
        from viewcomp.calib.world.audience import parse_audience

        v = cal.rig.viewer
        audience = parse_audience(args.audience, v.distance, v.height or 0.0)
        if len(audience) > 1 and args.method != "pixel":
            raise UsageError("--audience with several viewers needs --method pixel")
        eyes = list(audience.eyes)
    else:
        eyes = [cal.eye(args.angle, parse_vec3(args.eye) if args.eye else None)]
    h, w = cal.shape
    if is_image(src):
        images = [("", fit_rgb(read_rgb8(src), w, h))]
    else:
        images = [(f"{t:.2f} s", rgb) for t, rgb in _video_frames(src, (w, h), args.frames)]
        if not images:
            raise UsageError(f"{src} has no video frames to preview; give another video")
    lam = DEFAULT_LAMBDA if args.lam is None else args.lam
    comp = Compensation(cal, args.method, lam)
    previews = []
    for label, rgb in images:
        for eye in eyes:
            angle = eye_to_polar(eye)[0]
            where = f"{angle:.0f} deg, eye ({eye[0]:+.3f}, {eye[1]:+.3f}, {eye[2]:+.3f}) m"
            p = predict(comp, np.ascontiguousarray(rgb, dtype=np.uint8), eye, audience)
            previews.append(
                (f"seen at {where}" if not label else f"{label}, seen at {angle:.0f} deg", p)
            )
    if audience is not None and len(audience) > 1:
        who = f"an audience of {len(audience)} viewers (one row each)"
        what = f"over the {len(audience)} viewers"
    else:
        who, what = f"a viewer at {where}", f"at {angle:.0f} degrees"
    title = (
        f"predicted by the calibration for {who}; {METHOD_NAMES[args.method]}, mean "
        "CIEDE2000 vs the white screen"
    )
    write_png(out, preview_picture(previews, args.method, title))
    if reach_out is not None:
        _write_reach(cal, eyes, reach_out)
    unc = np.mean([p.de_uncompensated for _, p in previews])
    com = np.mean([p.de_compensated for _, p in previews])
    frames = f", {len(images)} frames" if len(images) > 1 else ""
    print(
        f"wrote {out}: predicted colour error {what}{frames} (mean): "
        f"uncompensated dE {unc:.1f}, compensated ({METHOD_NAMES[args.method]}) "
        f"dE {com:.1f}"
    )
    return 0
