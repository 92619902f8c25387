"""A host application that owns its GL context and embeds viewcomp's compensation.

The host here is a plain glfw window; a game engine or kiosk shell does the same with its
own context. Each frame it: reads its head tracker (simulated: the viewer walks from 60 to
120 degrees and back), moves the eye, and lets viewcomp draw the compensated frame into the
host's framebuffer (a viewport of the window), then draws its own UI on top and swaps.
viewcomp never touches the window, the swap or the event loop, draws only into the viewport
and leaves the host's GL state as it found it: this host keeps blending on for its UI.

    python examples/embed_host.py                       # built-in calibration and clip
    python examples/embed_host.py --calib screen.vcb --video clip.mp4
    python examples/embed_host.py --frames 60 --check   # headless check (e.g. under Xvfb)
    python examples/embed_host.py --texture             # frames from the host's GL texture

``--check`` compares one presented frame with the numpy reference
(viewcomp.calib.model.reference.compensate with the same FrameParams) and exits non-zero if more
than 0.1 % of pixel-channels differ by more than one level.
"""

from __future__ import annotations

import sys
from pathlib import Path

# The repository on sys.path: the synthetic models and calibrations are tests.support's.
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import argparse
import math
import time

import glfw
import moderngl
import numpy as np

from tests.support.synthetic import smooth_frame
from viewcomp.calib.fit.calibrate import Calibration
from viewcomp.calib.model.reference import compensate
from viewcomp.rt.media.frames import Planes, yuv420p_to_rgb
from viewcomp.rt.media.video import VideoReader
from viewcomp.rt.play.embed import LiveRenderer


def tracker_angle(t: float) -> float:
    """The host's head tracker (simulated): 90 +- 30 degrees, one sweep every 8 s."""
    return 90.0 + 30.0 * math.sin(2.0 * math.pi * t / 8.0)


def frames(video: str | None, grid: tuple[int, int]):
    """The host's frames: a video's planes (looped), or a moving synthetic RGB picture."""
    if video is None:
        w, h = grid
        base = smooth_frame(2 * w, h, seed=2)
        i = 0
        while True:
            yield np.ascontiguousarray(base[:, i % w : i % w + w])
            i += 2
    while True:
        with VideoReader(video, fit=grid, audio="none") as reader:
            for item in reader:
                if isinstance(item, Planes):
                    yield item


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--calib", help="calibration bundle (default: a small simulated one)")
    ap.add_argument("--video", help="a video file (default: synthetic frames)")
    ap.add_argument("--size", default="960x540", help="host window size WxH")
    ap.add_argument("--frames", type=int, default=0, help="stop after N frames (0: never)")
    ap.add_argument("--check", action="store_true", help="check a frame against numpy")
    ap.add_argument("--texture", action="store_true",
                    help="hand viewcomp the frame in a GL texture of the host's")  # fmt: skip
    args = ap.parse_args()

    if args.calib:
        cal = Calibration.load(args.calib)
    else:
        from tests.support.calibrations import small_calibration

        cal = small_calibration(160, 90, screen="magenta")
    width, height = (int(v) for v in args.size.split("x"))

    # --- the host's own window and context ----------------------------------------------
    if not glfw.init():
        print("no display (set DISPLAY, or run under Xvfb)", file=sys.stderr)
        return 2
    glfw.window_hint(glfw.CONTEXT_VERSION_MAJOR, 3)
    glfw.window_hint(glfw.CONTEXT_VERSION_MINOR, 3)
    glfw.window_hint(glfw.OPENGL_PROFILE, glfw.OPENGL_CORE_PROFILE)
    glfw.window_hint(glfw.OPENGL_FORWARD_COMPAT, True)
    window = glfw.create_window(width, height, "host with viewcomp", None, None)
    glfw.make_context_current(window)
    glfw.swap_interval(1)
    ctx = moderngl.create_context(require=330)

    # --- viewcomp, embedded -----------------------------------------------------------------
    live = LiveRenderer(cal, ctx, angle=tracker_angle(0.0), eye_tau=0.1)
    host_tex = ctx.texture(live.grid, 3, dtype="f1")  # where the host keeps its frame
    ctx.enable(moderngl.BLEND)  # the host's UI blends; viewcomp switches it off and back
    status = 0
    try:
        t0 = time.monotonic()
        for n, frame in enumerate(frames(args.video, live.grid)):
            if glfw.window_should_close(window) or (args.frames and n >= args.frames):
                break
            glfw.poll_events()
            live.set_angle(tracker_angle(time.monotonic() - t0))  # from the host's tracker
            fw, fh = glfw.get_framebuffer_size(window)
            ctx.screen.use()
            ctx.viewport = (0, 0, fw, fh)
            ctx.clear(0.1, 0.1, 0.1)  # the host's own background
            if args.texture:  # e.g. a frame the host decoded or rendered on the GPU
                rgb = yuv420p_to_rgb(frame) if isinstance(frame, Planes) else frame
                host_tex.write(np.ascontiguousarray(rgb[::-1]))  # GL rows: bottom first
                record = live.render_texture(host_tex.glo, live.grid, target=ctx.screen,
                                             viewport=(0, 0, *live.grid), components=3)  # fmt: skip
            else:
                record = live.render(frame, target=ctx.screen, viewport=(0, 0, *live.grid))
            if args.check and n == 10:
                shot = np.frombuffer(ctx.screen.read(viewport=(0, 0, *live.grid)), np.uint8)
                shot = shot.reshape(live.grid[1], live.grid[0], 3)[::-1]
                rgb = yuv420p_to_rgb(frame) if isinstance(frame, Planes) else frame
                p = record.params
                ref = compensate(p.model, rgb, record.eye, p.alpha, p.beta)
                diff = np.abs(shot.astype(int) - ref.astype(int))
                over = int((diff > 1).sum())
                print(f"frame {n}: eye {np.round(record.eye, 4).tolist()} m, alpha "
                      f"{p.alpha:.3f}, beta {p.beta:.4f}; window vs numpy reference: max "
                      f"{diff.max()} level(s), {over} pixel-channel(s) over 1")  # fmt: skip
                status = 0 if over <= 0.001 * diff.size else 1
            glfw.swap_buffers(window)
    finally:
        live.release()  # viewcomp's GL objects; the context stays the host's
        host_tex.release()
        ctx.release()
        glfw.destroy_window(window)
        glfw.terminate()
    return status


if __name__ == "__main__":
    sys.exit(main())
