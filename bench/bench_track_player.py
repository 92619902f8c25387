"""Benchmark of `viewcomp play --track-camera`: camera frame -> eye in the player's picture,
with one core kept busy; prints one JSON object.

A simulated webcam (:func:`viewcomp.rt.track.simwalk.walk_camera`: 1280x720, 90 degrees
wide, 30 frames/s) films an empty room, then a face appearing at a new place (the astronaut
placed by her eyes, 1-3 m, 60-120 degrees), ``--appear`` times: each face stays ``--stay``
seconds, the room is empty ``--gap`` seconds between (longer than the tracker's 1 s hold, so
each face is a newcomer). The webcam behaves as a V4L2 device read through OpenCV: frames are
captured on their 30 frames/s schedule into ``--buffers`` driver buffers, a full queue drops
new captures, and each read returns the oldest one waiting (OpenCV asks for one buffer; not
every driver honours it: ``--buffers 4`` is the usual default of those that do not).

The path measured is the one ``play --track-camera`` builds: :class:`FrameSource` (its
reading loop, over the simulated device) -> :class:`Pipeline` (YuNet, the eye from the
landmarks, the filter) on a :class:`TrackerThread` -> the player's input hub -> a windowed
:class:`Player` (a private Xvfb, a 64x32 simulated calibration, a looping 30 frames/s clip,
eye smoothing off) whose ``on_frame`` sees the eye each frame is drawn with. Latency: the
presentation time of the first frame drawn with an eye minus the capture time of the camera
frame it came from (the frame's index is written into its corner pixels). ``appear``: the
first eye of each new face, from the frame it came from; ``entry``: the same eye from the
first frame the face was in (what a viewer walking in waits: the frames where the face was
not yet found count too); ``accurate``: from the same frame to the first eye drawn within 10
cm (x, y) and 10 % (distance) of the truth (a newcomer's first eye is a coarse reading, see
``viewcomp.rt.track.live_faces``); ``all``: every published eye. One process spins on a core for
the whole run. On a shared machine these vary with whoever else runs: compare rounds of one
run, never against a fixed number. Run from the repository root::

    .venv/bin/python bench/bench_track_player.py [--appear 6] [--buffers 4] [--rounds 2]
"""

from __future__ import annotations

import sys
from pathlib import Path

# The repository on sys.path: the synthetic calibration and clip are tests.support's.
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import argparse
import collections
import datetime
import json
import math
import multiprocessing
import os
import tempfile
import threading
import time
from dataclasses import replace

import numpy as np

from tests.support.calibrations import small_calibration
from tests.support.synthetic import make_test_video
from viewcomp.calib.world.eye import eye_from_angle
from viewcomp.rt.play.player import Player, PlayerOptions
from viewcomp.rt.play.xvfb import Xvfb, xvfb_available
from viewcomp.rt.track.run import Pipeline, TrackerThread, default_options
from viewcomp.rt.track.simwalk import background, render_frame, walk_camera
from viewcomp.rt.track.source import FrameSource
from viewcomp.rt.track.yunet import Faces

FPS = 30.0


def stamp(image: np.ndarray, index: int) -> np.ndarray:
    """A copy of ``image`` with ``index`` in its top-left pixel (3 bytes, BGR), where no
    face is ever drawn."""
    out = image.copy()
    out[0, 0] = (index & 255, (index >> 8) & 255, (index >> 16) & 255)
    return out


def index_of(image: np.ndarray) -> int:
    """The index :func:`stamp` wrote."""
    b, g, r = (int(v) for v in image[0, 0])
    return b | (g << 8) | (r << 16)


class SimulatedCapture:
    """A ``cv2.VideoCapture`` of a camera filming ``plan`` (one base image per frame):
    captures at ``t0 + i / fps`` into at most ``buffers`` queued driver buffers (a full queue
    drops the capture), ``read()`` returns the oldest queued frame or waits for the next."""

    def __init__(self, plan: list[np.ndarray], fps: float, buffers: int) -> None:
        self.plan, self.fps, self.buffers = plan, fps, max(1, buffers)
        self.t0 = math.inf  # streaming starts at the first read
        self._next = 0  # the next capture not yet taken into the queue
        self._queue: collections.deque[int] = collections.deque()
        self.dropped = 0

    def capture_time(self, index: int) -> float:
        return self.t0 + index / self.fps

    def _fill(self) -> None:
        newest = int((time.monotonic() - self.t0) * self.fps)
        while self._next <= min(newest, len(self.plan) - 1):
            if len(self._queue) < self.buffers:
                self._queue.append(self._next)
            else:
                self.dropped += 1
            self._next += 1

    def read(self) -> tuple[bool, np.ndarray | None]:
        if self.t0 == math.inf:
            self.t0 = time.monotonic()
        self._fill()
        if not self._queue:
            if self._next >= len(self.plan):
                return False, None
            time.sleep(max(0.0, self.capture_time(self._next) - time.monotonic()))
            self._fill()
        i = self._queue.popleft()
        return True, stamp(self.plan[i], i)

    def release(self) -> None:
        """Nothing to release."""


def simulated_source(capture: SimulatedCapture) -> FrameSource:
    """A :class:`FrameSource` reading ``capture`` as it reads a camera index (live)."""
    src = FrameSource.__new__(FrameSource)
    src.src, src.fps, src.realtime, src.live = "<simulated webcam>", capture.fps, False, True
    src._cap, src._files, src._first, src._reader = capture, [], None, None  # type: ignore[assignment]
    h, w = capture.plan[0].shape[:2]
    src.size = (w, h)
    return src


def placements(appear: int) -> list[tuple[float, float]]:
    """(angle degrees, distance m) of each face, spread over 60-120 degrees and 1-3 m."""
    return [
        (60.0 + 60.0 * ((k * 0.37) % 1.0), 1.0 + 2.0 * ((k * 0.61) % 1.0)) for k in range(appear)
    ]


def scene(appear: int, gap: float, stay: float) -> tuple[list[np.ndarray], list[int]]:
    """The frames' base images and the index of each face's first frame."""
    dev = walk_camera()
    rng = np.random.default_rng(5)
    back = background(dev.resolution, 0)
    empty = render_frame(dev, np.zeros((0, 3)), back, rng)
    plan: list[np.ndarray] = []
    firsts = []
    for angle, dist in placements(appear):
        face = render_frame(dev, eye_from_angle(angle, dist, 0.15)[None], back, rng)
        plan += [empty] * round(gap * FPS)
        firsts.append(len(plan))
        plan += [face] * round(stay * FPS)
    return plan + [empty] * round(0.5 * FPS), firsts


def _spin(stop: multiprocessing.synchronize.Event) -> None:  # type: ignore[name-defined]
    """Keep one core busy until ``stop`` is set."""
    x = 0
    while not stop.is_set():
        for _ in range(100_000):
            x += 1


def _stats(ms: list[float]) -> dict[str, float | int]:
    a = np.asarray(ms, np.float64)
    if a.size == 0:
        return {"n": 0}
    return {
        "n": int(a.size),
        "median_ms": round(float(np.median(a)), 1),
        "p95_ms": round(float(np.percentile(a, 95)), 1),
        "max_ms": round(float(a.max()), 1),
        "within_100ms": round(float(np.mean(a <= 100.0)), 3),
    }


def latencies(
    published: list[tuple[int, float, np.ndarray, bool]],
    drawn: list[tuple[float, np.ndarray]],
    capture: SimulatedCapture,
    firsts: list[int],
    stay: int,
    truths: list[np.ndarray] | None = None,
    camera: np.ndarray | None = None,
) -> dict:
    """The round's latencies: each published eye (frame index, when published, eye, whether
    its frame found a face) matched to the first frame ``drawn`` with it (presentation time,
    eye); ``firsts``: each face's first frame, ``stay``: the frames it stays; ``truths``:
    each face's true eye (3,) metres and ``camera`` (3,) the tracking camera's position, for
    ``accurate`` (from the face's first frame to the first eye drawn within 10 cm in x and y
    and 10 % in distance from the camera of the truth) and each first eye's distance ratio."""
    times = np.array([t for t, _ in drawn])
    eyes = np.array([e for _, e in drawn])
    lat, track_ms, appear = [], [], []
    entry: dict[int, float] = {}  # face's first frame -> ms from its capture to its first eye
    first_eye: dict[int, list[float]] = {}
    first_set = set(firsts)
    for index, done, eye, found in published:
        hit = np.flatnonzero((times >= done) & np.all(np.abs(eyes - eye) < 2e-4, axis=1))
        if not len(hit):
            continue  # replaced by a newer eye before a frame was drawn
        ms = 1e3 * (times[hit[0]] - capture.capture_time(index))
        lat.append(ms)
        track_ms.append(1e3 * (done - capture.capture_time(index)))
        # A face's first eye: the first drawn eye of a frame where the face was found (with
        # nobody found the tracker holds, then eases its last eye home: those eyes are not
        # the newcomer's).
        face = max((f for f in firsts if f <= index), default=-1)
        if found and face in first_set and face not in entry and index < face + stay:
            appear.append(ms)
            entry[face] = 1e3 * (times[hit[0]] - capture.capture_time(face))
            first_eye[face] = [float(v) for v in eye]
    out = {
        "appear": _stats(appear),
        "appear_ms": [round(v, 1) for v in appear],
        "entry": _stats(list(entry.values())),
        "entry_ms": [round(entry[f], 1) if f in entry else None for f in firsts],
        "first_eye_m": [first_eye.get(f) for f in firsts],
        "all": _stats(lat),
        "capture_to_published": _stats(track_ms),
    }
    if truths is not None and camera is not None:
        out.update(accuracy(drawn, capture, firsts, stay, truths, camera, first_eye))
    return out


def accuracy(
    drawn: list[tuple[float, np.ndarray]],
    capture: SimulatedCapture,
    firsts: list[int],
    stay: int,
    truths: list[np.ndarray],
    camera: np.ndarray,
    first_eye: dict[int, list[float]],
) -> dict:
    """Each face's first eye's distance ratio (to the truth, from ``camera``) and the ms from
    its first frame to the first eye drawn within 10 cm (x, y) and 10 % (distance) of it
    (see :func:`latencies`)."""
    ratio, accurate = [], []
    for f, truth in zip(firsts, truths, strict=True):
        t0, t1 = capture.capture_time(f), capture.capture_time(f + stay)
        want = float(np.linalg.norm(truth - camera))
        eye = first_eye.get(f)
        ratio.append(None if eye is None else round(float(np.linalg.norm(eye - camera)) / want, 3))
        ms = None
        for t, e in drawn:
            close = np.all(np.abs(e[:2] - truth[:2]) <= 0.1)
            if t0 <= t < t1 and close and abs(np.linalg.norm(e - camera) / want - 1) <= 0.1:
                ms = round(1e3 * (t - t0), 1)
                break
        accurate.append(ms)
    return {
        "first_eye_distance_ratio": ratio,
        "accurate": _stats([v for v in accurate if v is not None]),
        "accurate_ms": accurate,
    }


def one_round(
    plan: list[np.ndarray], firsts: list[int], stay: int, buffers: int, clip: Path
) -> dict:
    """One run over the scene; ``stay``: the frames each face stays."""
    cal = small_calibration(64, 32, screen="magenta")
    cal = replace(cal, rig=replace(cal.rig, tracker=walk_camera()))
    capture = SimulatedCapture(plan, FPS, buffers)
    pipeline = Pipeline(simulated_source(capture), walk_camera(), default_options(cal.rig))
    # frame index, done, eye, whether that frame's search found a face
    published: list[tuple[int, float, np.ndarray, bool]] = []
    step, step_ms = pipeline.step, []

    def recorded(frame):  # type: ignore[no-untyped-def]
        t0 = time.perf_counter()
        res = step(frame)
        step_ms.append(1e3 * (time.perf_counter() - t0))
        if res.sent and len(res.eyes):
            eye = np.round(res.eyes[0], 4)
            published.append((index_of(frame.image), res.done, eye, len(res.raw) > 0))
        return res

    pipeline.step = recorded  # type: ignore[method-assign]
    assert pipeline.yunet is not None
    pipeline.yunet.detect(plan[0])  # the network's first run sets it up (slow, once)
    detect, detect_ms = pipeline.yunet.detect, []

    def timed_detect(image: np.ndarray, follow: np.ndarray | None = None) -> Faces:
        t0 = time.perf_counter()
        out = detect(image, follow=follow)
        detect_ms.append(1e3 * (time.perf_counter() - t0))
        return out

    pipeline.yunet.detect = timed_detect  # type: ignore[method-assign]
    tracker = TrackerThread(pipeline, all_faces=True)
    drawn: list[tuple[float, np.ndarray]] = []

    def on_frame(player: Player, f: object) -> None:
        drawn.append((max(time.monotonic(), f.due), np.asarray(f.record.eye)))  # type: ignore[attr-defined]
        if time.monotonic() > capture.capture_time(len(plan)) + 1.0:
            player.stop()

    seconds = len(plan) / FPS + 60.0
    opts = PlayerOptions(windowed=True, audio=False, stdin_fd=None, loop=True, eye_tau=0.0,
                         max_seconds=seconds, inputs=(tracker,))  # fmt: skip
    Player(cal, [clip], opts, on_frame=on_frame).run()
    n = pipeline.stats.frames
    truths = [eye_from_angle(a, d, 0.15) for a, d in placements(len(firsts))]
    camera = np.asarray(walk_camera().position, np.float64)
    return {
        **latencies(published, drawn, capture, firsts, stay, truths, camera),
        "faces": len(firsts),
        "published": len(published),
        "frames_read": pipeline.stats.frames,
        "captures_dropped_by_driver": capture.dropped,
        "frames_skipped_by_reader": getattr(pipeline.source, "dropped", None),
        "tracker_ms_per_frame": round(1e3 * pipeline.stats.seconds / max(n, 1), 1),
        "detect_ms_median": round(float(np.median(detect_ms)), 1) if detect_ms else None,
        "step_ms_median": round(float(np.median(step_ms)), 1) if step_ms else None,
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--appear", type=int, default=6, help="faces appearing (default 6)")
    ap.add_argument("--gap", type=float, default=1.5, help="seconds of empty room before each")
    ap.add_argument("--stay", type=float, default=1.0, help="seconds each face stays")
    ap.add_argument("--buffers", type=int, default=4, help="driver buffers (default 4)")
    ap.add_argument("--rounds", type=int, default=2, help="runs over the same scene")
    ap.add_argument("--no-spin", action="store_true", help="leave every core to the run")
    ap.add_argument(
        "--cv-threads", type=int, default=None, help="cv2.setNumThreads (default: OpenCV's)"
    )
    args = ap.parse_args(argv)
    if args.cv_threads is not None:
        import cv2

        cv2.setNumThreads(args.cv_threads)
    if not xvfb_available():
        print("bench_track_player: Xvfb is not installed (Debian package xvfb)", file=sys.stderr)
        return 2
    plan, firsts = scene(args.appear, args.gap, args.stay)
    stop = multiprocessing.Event()
    spinner = multiprocessing.Process(target=_spin, args=(stop,), daemon=True)
    if not args.no_spin:
        spinner.start()
    try:
        with tempfile.TemporaryDirectory() as tmp, Xvfb((640, 360)):
            clip = Path(tmp) / "clip.mp4"
            make_test_video(str(clip), 128, 64, seconds=4.0, rate=30, audio=False)
            rounds = [
                one_round(plan, firsts, round(args.stay * FPS), args.buffers, clip)
                for _ in range(args.rounds)
            ]
    finally:
        stop.set()
        if spinner.is_alive():
            spinner.join(timeout=5)
    result = {
        "bench": "track_player",
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "cpus": os.cpu_count(),
        "load_average": [round(v, 2) for v in os.getloadavg()],
        "core_busy": not args.no_spin,
        "camera": {"resolution": [1280, 720], "fps": FPS, "buffers": args.buffers},
        "cv_threads": args.cv_threads,
        "scene": {
            "appear": args.appear,
            "gap_s": args.gap,
            "stay_s": args.stay,
            "faces_angle_deg_distance_m": placements(args.appear),
        },
        "rounds": rounds,
    }
    print(json.dumps(result, indent=1))
    if not any(r["published"] for r in rounds):  # the tracker stopped: no figure to trust
        print("bench_track_player: no eye was published (see above)", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    threading.current_thread().name = "bench"
    raise SystemExit(main())
