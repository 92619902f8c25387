"""Benchmark of `viewcomp track`: camera frame -> eye at the player; prints one JSON object.

A simulated tracking camera (:mod:`viewcomp.rt.track.simwalk`: 1280x720, 90 degrees wide)
delivers frames at 30 frames/s: first an empty room for ``--empty`` seconds, then the walk
(1..3 m, 90 +- 40 degrees). Each frame is stamped when the camera would have captured it
(its place in the 30 frames/s schedule); if the tracker falls behind, the wait counts. The
tracker publishes every new eye twice, as the player receives it:

- ``pipe``: an ``eye X Y Z`` line on an os.pipe, read by the player's own stdin reader
  (:class:`viewcomp.rt.play.live.LineReader`) into an :class:`~viewcomp.rt.play.live.InputHub`;
- ``osc``: an OSC ``/viewcomp/eye`` datagram to 127.0.0.1, read by the player's own
  :class:`viewcomp.rt.play.live.OscListener` into a hub.

Latency is the hub's arrival time minus the frame's capture time, per published frame;
``appear`` is the first frame of a face after the empty room (found by a full-frame search,
the slowest kind of frame). Also printed: the search's settings and the time per stage.
On a shared machine these vary with whoever else runs: compare rounds of one run, never
against a fixed number (the tests assert accuracy, never time). Run from the repository root::

    .venv/bin/python bench/bench_track.py [--seconds 12] [--empty 1] [--rounds 2]
"""

from __future__ import annotations

import argparse
import datetime
import io
import json
import os
import threading
import time
from collections.abc import Iterator
from dataclasses import asdict

import numpy as np

from viewcomp.rt.play.live import InputHub, LineReader, OscListener
from viewcomp.rt.track.publish import LinePublisher, OscPublisher
from viewcomp.rt.track.run import Pipeline, TrackOptions
from viewcomp.rt.track.simwalk import background, render_frame, render_walk, walk, walk_camera
from viewcomp.rt.track.source import Frame

FPS = 30.0


class PacedCamera:
    """Frames in memory captured on a 30 frames/s schedule and stamped with their capture
    times; like a webcam with a one-frame buffer (what FrameSource asks a device for), a
    reader that is busy gets the newest frame and the ones in between are dropped."""

    live = True
    src = "<simulated camera>"

    def __init__(self, images: list[np.ndarray], fps: float = FPS) -> None:
        self.images, self.fps = images, fps
        h, w = images[0].shape[:2]
        self.size = (w, h)
        self.dropped = 0

    def __iter__(self) -> Iterator[Frame]:
        start = time.monotonic() + 0.2
        last = -1
        while True:
            newest = int((time.monotonic() - start) * self.fps)
            if newest <= last:  # wait for the next capture
                time.sleep(max(0.0, start + (last + 1) / self.fps - time.monotonic()))
                newest = last + 1
            if newest >= len(self.images):
                return
            self.dropped += newest - last - 1
            last = newest
            yield Frame(self.images[newest], newest / self.fps, newest, start + newest / self.fps)

    def close(self) -> None:
        """Nothing to release."""


def _stats(ms: list[float]) -> dict[str, float | int]:
    a = np.asarray(ms, np.float64)
    if a.size == 0:
        return {"n": 0}
    return {
        "n": int(a.size),
        "median_ms": round(float(np.median(a)), 1),
        "p95_ms": round(float(np.percentile(a, 95)), 1),
        "max_ms": round(float(a.max()), 1),
        "within_100ms": round(float(np.mean(a <= 100.0)), 4),
    }


def one_round(images: list[np.ndarray], empty_frames: int) -> dict[str, object]:
    dev = walk_camera()
    hub_pipe, hub_osc = InputHub(), InputHub()
    r, w = os.pipe()
    reader = LineReader(hub_pipe, r).start()
    listener = OscListener(hub_osc, "127.0.0.1", 0).start()
    stream = io.TextIOWrapper(os.fdopen(w, "wb", buffering=0), write_through=True)
    line_pub = LinePublisher(stream)
    osc_pub = OscPublisher(*listener.address)
    options = TrackOptions(detector_kind="cascade")  # its stages (full-frame searches) are timed
    pipeline = Pipeline(PacedCamera(images), dev, options, [line_pub, osc_pub])  # type: ignore[arg-type]
    sent: list[tuple[int, float]] = []  # (frame index, capture time) of each published eye
    stage = {"detect_ms": [], "rest_ms": [], "full_frames": []}
    detect = pipeline.detector.detect

    def timed_detect(
        frame: np.ndarray, hints: np.ndarray | None = None, **kw: object
    ) -> np.ndarray:
        before = pipeline.detector.full_searches
        t0 = time.perf_counter()
        out = detect(frame, hints, **kw)  # type: ignore[arg-type]
        stage["detect_ms"].append(1e3 * (time.perf_counter() - t0))
        stage["full_frames"].append(pipeline.detector.full_searches > before)
        return out

    pipeline.detector.detect = timed_detect  # type: ignore[method-assign]
    per_frame_ms = []
    for frame in pipeline.source:
        res = pipeline.step(frame)
        per_frame_ms.append(1e3 * (res.done - frame.captured))
        stage["rest_ms"].append(per_frame_ms[-1] - stage["detect_ms"][-1])
        if res.sent:
            sent.append((frame.index, frame.captured))
    time.sleep(0.3)
    pipeline.close()
    stream.close()
    reader.stop()
    listener.stop()
    osc_pub.close()
    os.close(r)
    out: dict[str, object] = {}
    for name, hub in (("pipe", hub_pipe), ("osc", hub_osc)):
        got = hub.drain()
        n = min(len(got), len(sent))
        lat = [1e3 * (got[k].at - sent[k][1]) for k in range(n)]
        out[name] = _stats(lat)
        appear = [k for k in range(n) if sent[k][0] >= empty_frames]
        if appear:
            out[name]["appear_ms"] = round(lat[appear[0]], 1)  # type: ignore[index]
            out[name]["appear_frame"] = sent[appear[0]][0]  # type: ignore[index]
        out[name]["received"] = len(got)  # type: ignore[index]
    full = np.asarray(stage["full_frames"])
    det = np.asarray(stage["detect_ms"])
    out["published"] = len(sent)
    out["frames"] = pipeline.stats.frames
    out["frames_dropped_by_camera"] = pipeline.source.dropped  # type: ignore[union-attr]
    out["frames_with_face"] = pipeline.stats.with_face
    out["detect_ms"] = {
        "tracked_median": round(float(np.median(det[~full])), 1) if (~full).any() else None,
        "full_search_median": round(float(np.median(det[full])), 1) if full.any() else None,
        "full_search_frames": int(full.sum()),
    }
    out["rest_ms_median"] = round(float(np.median(stage["rest_ms"])), 2)
    out["frame_to_published_ms"] = _stats(per_frame_ms)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=12.0, help="length of the walk (default 12)")
    ap.add_argument("--empty", type=float, default=1.0, help="seconds of empty room first")
    ap.add_argument("--rounds", type=int, default=2, help="runs over the same frames")
    args = ap.parse_args(argv)
    dev = walk_camera()
    _, eyes = walk(args.seconds, FPS)
    rng = np.random.default_rng(7)
    back = background(dev.resolution, 0)
    n_empty = round(args.empty * FPS)
    images = [render_frame(dev, np.zeros((0, 3)), back, rng) for _ in range(n_empty)]
    images += render_walk(dev, eyes, seed=0)
    pipeline = Pipeline(PacedCamera(images[:1]), dev, TrackOptions(detector_kind="cascade"))
    result = {
        "bench": "track",
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "cpus": os.cpu_count(),
        "camera": {"resolution": list(dev.resolution), "fov_y": dev.fov_y, "fps": FPS},
        "detector": asdict(pipeline.detector.config),
        "frames": len(images),
        "rounds": [one_round(images, n_empty) for _ in range(args.rounds)],
    }
    print(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    threading.current_thread().name = "bench"
    raise SystemExit(main())
