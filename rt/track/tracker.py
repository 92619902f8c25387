"""Viewers over time: detections -> smoothed eyes, held when lost, then the default eye.

Each viewer is a :class:`Track`: the eye estimated from its face, smoothed by a One-Euro
filter (:mod:`viewcomp.rt.track.filter`) of its own, a velocity and the box where its face was
last seen (the detector's hint for the next frame). A new frame's eyes are assigned to the
tracks' *predicted* eyes (last eye + velocity x time since seen) by the Hungarian method on
distance (``scipy.optimize.linear_sum_assignment``: the least total distance, so two viewers
who cross keep their identities where a nearest-first choice could swap them), a pair farther
than ``gate`` metres is not a match; an unmatched eye starts a track (a viewer entering); a
track not seen for ``hold`` seconds ends (a viewer leaving).

What is published (:meth:`EyeTracker.update`):

- ``faces="nearest"``: one eye: the nearest viewer's (distance from the screen centre, the
  world origin), kept while it is seen or held unless another viewer is seen nearer by
  ``switch_margin`` metres (so two viewers at about the same distance, or a frame that
  misses one of them, do not flip the picture). A viewer no longer seen is held for
  ``hold`` seconds; then another seen viewer is followed, or, with nobody seen, the eye
  eases to ``default_eye`` over ``ease`` seconds (smoothstep). Before anyone was seen it is
  ``default_eye``.
- ``faces="all"``: every current track's eye (held ones included), nearest first; when
  there is none, the single eye that ``"nearest"`` would publish, so there is always one.

Times are seconds on any clock that increases (a camera's frame times).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from viewcomp.rt.track.filter import OneEuroFilter


@dataclass
class TrackerConfig:
    """Tracking settings; times in seconds, positions in metres (world frame).

    ``min_cutoff`` (Hz) and ``beta`` (Hz per m/s) are the One-Euro filter's, ``d_cutoff``
    its speed estimate's cutoff (Hz).
    """

    faces: str = "nearest"
    default_eye: tuple[float, float, float] = (0.0, 0.0, 2.0)
    hold: float = 1.0
    ease: float = 1.0
    min_cutoff: float = 2.0
    beta: float = 5.0
    d_cutoff: float = 1.0
    gate: float = 0.5
    switch_margin: float = 0.3


@dataclass
class Track:
    """One viewer: ``eye`` (3,) the filtered eye, ``box`` (4,) the last face box (pixels),
    ``seen`` the time of the last detection, ``id`` a number unique in a tracker, ``index``
    the detection it was last given (its row in that frame's eyes), ``template`` whatever
    the caller keeps per viewer (the pipeline: its face template, or None)."""

    id: int
    filter: OneEuroFilter
    eye: np.ndarray
    box: np.ndarray
    seen: float
    index: int = -1
    template: Any = None
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def predict(self, t: float, horizon: float = 0.5) -> np.ndarray:
        """(3,) the eye expected at time t: the last eye moved on by the velocity for at
        most ``horizon`` seconds (a held viewer is not extrapolated far)."""
        return self.eye + self.velocity * min(max(t - self.seen, 0.0), horizon)


def _smoothstep(s: float) -> float:
    s = min(max(s, 0.0), 1.0)
    return s * s * (3.0 - 2.0 * s)


@dataclass
class EyeTracker:
    """The state between frames; feed it with :meth:`update` once per frame."""

    config: TrackerConfig = field(default_factory=TrackerConfig)
    tracks: list[Track] = field(default_factory=list)

    def __post_init__(self) -> None:
        if self.config.faces not in ("nearest", "all"):
            raise ValueError(f'faces is "nearest" or "all", got {self.config.faces!r}')
        self._next_id = 0
        self._chosen: int | None = None  # the id of the viewer "nearest" follows
        self._lost_at: float | None = None  # when the followed viewer was last seen
        self._lost_eye = np.asarray(self.config.default_eye, np.float64)

    def hints(self) -> np.ndarray:
        """(K, 4) boxes where the current tracks' faces were last seen."""
        return np.asarray([t.box for t in self.tracks], np.float64).reshape(-1, 4)

    def _match(self, eyes: np.ndarray, boxes: np.ndarray, t: float) -> None:
        from scipy.optimize import linear_sum_assignment

        c = self.config
        used_e: set[int] = set()
        if len(eyes) and self.tracks:
            pred = np.asarray([tr.predict(t) for tr in self.tracks])
            cost = np.linalg.norm(eyes[:, None, :] - pred[None, :, :], axis=2)  # (N, K)
            gated = np.where(cost <= c.gate, cost, 1e6)  # a pair beyond the gate is no match
            rows, cols = linear_sum_assignment(gated)
            for i, k in zip(rows.tolist(), cols.tolist(), strict=True):
                if cost[i, k] > c.gate:
                    continue
                used_e.add(i)
                tr = self.tracks[k]
                if t - tr.seen > c.hold:  # back after a gap: no smoothing from where it was
                    tr.filter.reset()
                    tr.velocity = np.zeros(3)
                before, dt = tr.eye, t - tr.seen
                tr.eye = tr.filter(eyes[i], t)
                if 0.0 < dt <= c.hold:  # smoothed velocity of the filtered eye, m/s
                    v = (tr.eye - before) / dt
                    tr.velocity = 0.5 * tr.velocity + 0.5 * v
                tr.box = boxes[i].copy()
                tr.seen = t
                tr.index = i
        for i in range(len(eyes)):
            if i not in used_e:
                f = OneEuroFilter(c.min_cutoff, c.beta, c.d_cutoff)
                self.tracks.append(Track(self._next_id, f, f(eyes[i], t), boxes[i].copy(), t, i))
                self._next_id += 1
        self.tracks = [tr for tr in self.tracks if t - tr.seen <= c.hold]

    def _nearest(self, t: float) -> np.ndarray:
        """The eye of ``faces="nearest"`` at time t (tracks already updated)."""
        c = self.config
        seen = [tr for tr in self.tracks if tr.seen == t]
        # the followed viewer, seen now or held (not seen for at most `hold` seconds)
        current = next((tr for tr in self.tracks if tr.id == self._chosen), None)
        if seen:
            best = min(seen, key=lambda tr: float(np.linalg.norm(tr.eye)))
            if current is None or (
                float(np.linalg.norm(current.eye)) - float(np.linalg.norm(best.eye))
                > c.switch_margin
            ):
                current = best
        if current is not None:
            self._chosen = current.id
            self._lost_at = current.seen
            self._lost_eye = current.eye.copy()
            return current.eye.copy()
        default = np.asarray(c.default_eye, np.float64)
        if self._lost_at is None:
            return default
        since = t - self._lost_at
        if since <= c.hold:
            return self._lost_eye.copy()
        k = 1.0 if c.ease <= 0 else _smoothstep((since - c.hold) / c.ease)
        return (1.0 - k) * self._lost_eye + k * default

    def update(self, eyes: np.ndarray, boxes: np.ndarray, t: float) -> np.ndarray:
        """One frame's detections -> the eyes to publish.

        Args:
            eyes: (N, 3) metres, the eyes estimated from this frame's faces (N may be 0).
            boxes: (N, 4) the faces' boxes (x, y, w, h), pixels, in the same order.
            t: the frame's time, seconds.

        Returns:
            (K, 3) float64 metres: K = 1 for ``"nearest"``, K >= 1 for ``"all"``.
        """
        e = np.asarray(eyes, np.float64).reshape(-1, 3)
        b = np.asarray(boxes, np.float64).reshape(-1, 4)
        self._match(e, b, float(t))
        one = self._nearest(float(t))
        if self.config.faces == "all" and self.tracks:
            ordered = sorted(self.tracks, key=lambda tr: float(np.linalg.norm(tr.eye)))
            return np.asarray([tr.eye for tr in ordered], np.float64)
        return one[None, :]
