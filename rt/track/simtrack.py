"""The simulated walk tracked: what the tracker reports for a viewer whose truth is known.

:func:`tracked_walk` renders the walk of :mod:`viewcomp.rt.track.simwalk` frame by frame (the
astronaut's face placed in 3-D in the tracking camera's frames, with sensor noise), runs the
tracking pipeline of ``viewcomp track`` on it (detector, face templates, One-Euro filter,
nearest face) as a file is run (one thread, reproducible), and returns the published eye of
every frame beside the truth. ``viewcomp evaluate --protocol audience`` compensates for the
tracked eye and judges what the true eye sees; tests and ``bench/bench_track.py`` measure
the tracker's accuracy on the same walk.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import overload

import numpy as np

from viewcomp.calib.world.rig import Device
from viewcomp.rt.track.run import Pipeline, TrackOptions
from viewcomp.rt.track.simwalk import background, render_frame, walk, walk_camera
from viewcomp.rt.track.source import ArraySource


class _Frames(Sequence[np.ndarray]):
    """The walk's frames rendered when read (a 12 s walk at 1280x720 is 1 GB held at once)."""

    def __init__(self, device: Device, eyes: np.ndarray, seed: int) -> None:
        self.device, self.eyes, self.seed = device, eyes, seed
        self.back = background(device.resolution, seed)

    def __len__(self) -> int:
        return len(self.eyes)

    @overload
    def __getitem__(self, i: int) -> np.ndarray: ...

    @overload
    def __getitem__(self, i: slice) -> Sequence[np.ndarray]: ...

    def __getitem__(self, i: int | slice) -> np.ndarray | Sequence[np.ndarray]:
        if isinstance(i, slice):
            return [self[j] for j in range(*i.indices(len(self)))]
        rng = np.random.default_rng((self.seed, i))
        return render_frame(self.device, self.eyes[i][None], self.back, rng)


def tracked_walk(
    seconds: float = 12.0,
    fps: float = 30.0,
    seed: int = 0,
    options: TrackOptions | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Track the simulated walk (:func:`viewcomp.rt.track.simwalk.walk`: 1..3 m, 90 +- 40
    degrees) seen by :func:`~viewcomp.rt.track.simwalk.walk_camera`.

    Args:
        seconds, fps: the walk's length and frame rate.
        seed: the background's and the noise's seed.
        options: the tracking pipeline's options (default: ``viewcomp track``'s).
        progress: called with (frames done, frames) every 30 frames.

    Returns:
        times (n,) seconds, the true eyes (n, 3) and the tracked eyes (n, 3), metres in the
        world frame; the tracked eye of frame i is what the pipeline published after it.
    """
    device = walk_camera()
    times, truth = walk(seconds, fps)
    frames = _Frames(device, truth, seed)
    pipeline = Pipeline(
        ArraySource(frames, fps, "<simulated walk>"),  # type: ignore[arg-type]  # list-like
        device,
        options or TrackOptions(),
    )
    tracked = np.empty_like(truth)
    try:
        for i, frame in enumerate(pipeline.source):
            tracked[i] = pipeline.step(frame).eyes[0]
            if progress is not None and (i + 1) % 30 == 0:
                progress(i + 1, len(frames))
    finally:
        pipeline.close()
    return times, truth, tracked
