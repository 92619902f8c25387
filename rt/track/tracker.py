"""Viewers over time: detections -> smoothed eyes, held when lost, then the default eye.

Each viewer is a :class:`Track`: the eye estimated from its face, smoothed by a One-Euro
filter (:mod:`viewcomp.rt.track.filter`) of its own, a velocity and the box where its face was
last seen (the detector's hint for the next frame). A new frame's eyes are assigned to the
tracks' *predicted* eyes (last eye + velocity x time since seen) by the Hungarian method on
distance (``scipy.optimize.linear_sum_assignment``: the least total distance, so two viewers
who cross keep their identities where a nearest-first choice could swap them), a pair farther
than ``gate`` metres is not a match; an unmatched eye starts a track (a viewer entering); a
track not seen for ``hold`` seconds ends (a viewer leaving).

Given the faces' landmark readings (:class:`~viewcomp.rt.track.anatomy.HeadPose`), each track
also learns its viewer's face height (eyes to mouth, metres) from the faces read frontal (a
running mean over about ``HEIGHT_FRAMES`` of them; a face the height already ranges nearer is
not taken: it is turned more than its nose says), and a face matched to it is ranged with
that height within what its IPD allows for the turn its nose reads
(:func:`~viewcomp.rt.track.anatomy.ranged_eyes`): the assignment compares each face, ranged
with each track's own height, to that track's prediction. Until a track has measured its
viewer's height (and for a face that starts a track), the typical adult's is used with a
wider spread (:func:`~viewcomp.rt.track.anatomy.prior_ranged_eyes`).

A reading marked coarse (a live newcomer's first, from the search's own landmarks) starts a
*provisional* track: it teaches no face height, the face whose box overlaps the track's box
is its own whatever its distance, the first refined reading restarts the filter there, and
until then it does not take ``"nearest"`` over from a viewer already followed.

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

from viewcomp.rt.track.anatomy import (
    FRONTAL,
    NEARER_FROM,
    NEARER_TO,
    HeadPose,
    face_height,
    prior_ranged_eyes,
    ranged_eyes,
)
from viewcomp.rt.track.boxes import SAME_FACE, iou
from viewcomp.rt.track.filter import OneEuroFilter

# A viewer's face height is the mean of its first HEIGHT_FRAMES frontal frames, then an
# exponential mean that gives each new one that weight (1 / HEIGHT_FRAMES).
HEIGHT_FRAMES = 30


def smoothstep(x: np.ndarray | float, lo: float = 0.0, hi: float = 1.0) -> np.ndarray:
    """0 at ``x`` <= ``lo``, 1 at ``x`` >= ``hi``, 3 t^2 - 2 t^3 of t = (x - lo) / (hi - lo)
    between (a ramp with flat ends)."""
    t = np.clip((np.asarray(x, np.float64) - lo) / (hi - lo), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


@dataclass
class TrackerConfig:
    """Tracking settings; times in seconds, positions in metres (world frame).

    ``min_cutoff`` (Hz) and ``beta`` (Hz per m/s) are the One-Euro filter's, ``d_cutoff``
    its speed estimate's cutoff (Hz). ``face_height``: learn each viewer's face height and
    range their turned faces by it (False: the IPD's range alone, as a comparison).
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
    face_height: bool = True


@dataclass
class Track:
    """One viewer: ``eye`` (3,) the filtered eye, ``box`` (4,) the last face box (pixels),
    ``seen`` the time of the last detection, ``id`` a number unique in a tracker, ``index``
    the detection it was last given (its row in that frame's eyes), ``template`` whatever
    the caller keeps per viewer (the pipeline: its face template, or None); ``raw`` (3,)
    the eye it was last given, before the filter; ``face_height`` metres, the viewer's eyes
    to mouth (NaN until a frontal face was seen), from ``frontal`` frames; ``provisional``:
    every reading so far was coarse (its first refined one starts the filter afresh)."""

    id: int
    filter: OneEuroFilter
    eye: np.ndarray
    box: np.ndarray
    seen: float
    index: int = -1
    template: Any = None
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))
    raw: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    face_height: float = float("nan")
    frontal: int = 0
    provisional: bool = False

    def measure(self, height: float, yaw: float, nearer: float = float("nan")) -> None:
        """Take one face's eye-to-mouth length (metres, :func:`face_height`) read at ``yaw``
        radians into the viewer's face height if the face was read frontal and the height
        known so far did not range it :data:`NEARER_FROM` nearer than its IPD (turned more
        than its nose says) nor :data:`NEARER_TO` farther (an outlier) (``nearer``:
        :func:`ranged_eyes`' share; NaN before a height is known)."""
        odd = not -NEARER_TO < nearer < NEARER_FROM if np.isfinite(nearer) else False
        if abs(yaw) < FRONTAL and not odd and np.isfinite(height) and height > 0:
            self.frontal = min(self.frontal + 1, HEIGHT_FRAMES)
            h = height if self.frontal == 1 else self.face_height
            self.face_height = h + (height - h) / self.frontal

    def predict(self, t: float, horizon: float = 0.5) -> np.ndarray:
        """(3,) the eye expected at time t: the last eye moved on by the velocity for at
        most ``horizon`` seconds (a held viewer is not extrapolated far)."""
        return self.eye + self.velocity * min(max(t - self.seen, 0.0), horizon)


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

    def _candidates(self, eyes: np.ndarray, pose: HeadPose | None) -> tuple[np.ndarray, np.ndarray]:
        """(N, K, 3): each face's eye as each track would range it (its face height; ``eyes``
        for a track that has none yet), and (N, K) how much nearer the height ranged it (a
        share; NaN: not ranged by a measured height)."""
        out = np.repeat(eyes[:, None, :], len(self.tracks), axis=1)
        nearer = np.full(out.shape[:2], np.nan)
        if pose is not None:
            for k, tr in enumerate(self.tracks):
                if np.isfinite(tr.face_height):
                    out[:, k], nearer[:, k] = ranged_eyes(pose, tr.face_height)
        return out, nearer

    def _match(
        self,
        eyes: np.ndarray,
        boxes: np.ndarray,
        t: float,
        pose: HeadPose | None,
        coarse: np.ndarray,
    ) -> None:
        from scipy.optimize import linear_sum_assignment

        c = self.config
        used_e: set[int] = set()
        heights = face_height(pose) if pose is not None else np.full(len(eyes), np.nan)
        heights = np.where(coarse, np.nan, heights)  # a coarse reading teaches no height
        yaws = pose.yaw if pose is not None else np.zeros(len(eyes))
        if pose is not None:  # before a viewer's own height: the typical adult's
            eyes = prior_ranged_eyes(pose)
        if len(eyes) and self.tracks:
            pred = np.asarray([tr.predict(t) for tr in self.tracks])
            cand, nearer = self._candidates(eyes, pose)
            cost = np.linalg.norm(cand - pred[None, :, :], axis=2)  # (N, K)
            # a provisional track's range is coarse, not its place in the picture: the face
            # whose box overlaps its box is its own, wherever the refined range puts it
            for k, tr in enumerate(self.tracks):
                if tr.provisional and len(boxes):
                    over = iou(tr.box, boxes)
                    cost[:, k] = np.where(over > SAME_FACE, (1.0 - over) * c.gate, cost[:, k])
            gated = np.where(cost <= c.gate, cost, 1e6)  # a pair beyond the gate is no match
            rows, cols = linear_sum_assignment(gated)
            for i, k in zip(rows.tolist(), cols.tolist(), strict=True):
                if cost[i, k] > c.gate:
                    continue
                used_e.add(i)
                tr = self.tracks[k]
                # back after a gap, or refined at last: no smoothing from where it was
                restart = t - tr.seen > c.hold or (tr.provisional and not coarse[i])
                if restart:
                    tr.filter.reset()
                    tr.velocity = np.zeros(3)
                tr.provisional = tr.provisional and bool(coarse[i])
                before, dt = tr.eye, t - tr.seen
                tr.raw = cand[i, k].copy()
                tr.eye = tr.filter(tr.raw, t)
                tr.measure(float(heights[i]), float(yaws[i]), float(nearer[i, k]))
                if 0.0 < dt and not restart:  # smoothed velocity of the filtered eye, m/s
                    v = (tr.eye - before) / dt
                    tr.velocity = 0.5 * tr.velocity + 0.5 * v
                tr.box = boxes[i].copy()
                tr.seen = t
                tr.index = i
        for i in range(len(eyes)):
            if i not in used_e:
                f = OneEuroFilter(c.min_cutoff, c.beta, c.d_cutoff)
                tr = Track(self._next_id, f, f(eyes[i], t), boxes[i].copy(), t, i)
                tr.raw = eyes[i].copy()
                tr.provisional = bool(coarse[i])
                tr.measure(float(heights[i]), float(yaws[i]))
                self.tracks.append(tr)
                self._next_id += 1
        self.tracks = [tr for tr in self.tracks if t - tr.seen <= c.hold]

    def _nearest(self, t: float) -> np.ndarray:
        """The eye of ``faces="nearest"`` at time t (tracks already updated)."""
        c = self.config
        seen = [tr for tr in self.tracks if tr.seen == t]
        # the followed viewer, seen now or held (not seen for at most `hold` seconds)
        current = next((tr for tr in self.tracks if tr.id == self._chosen), None)
        if current is not None:  # a coarse newcomer's distance takes over from no viewer
            seen = [tr for tr in seen if not tr.provisional]
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
        k = 1.0 if c.ease <= 0 else float(smoothstep((since - c.hold) / c.ease))
        return (1.0 - k) * self._lost_eye + k * default

    def update(
        self,
        eyes: np.ndarray,
        boxes: np.ndarray,
        t: float,
        pose: HeadPose | None = None,
        coarse: np.ndarray | None = None,
    ) -> np.ndarray:
        """One frame's detections -> the eyes to publish.

        Args:
            eyes: (N, 3) metres, the eyes estimated from this frame's faces (N may be 0).
            boxes: (N, 4) the faces' boxes (x, y, w, h), pixels, in the same order.
            t: the frame's time, seconds.
            pose: the same faces' landmark readings (``eyes`` is ``pose.eyes``), or None
                (a detector without landmarks): with it, tracks learn and use their
                viewers' face heights.
            coarse: (N,) bool, the readings from landmarks too coarse for the face's size
                (``Faces.coarse``: a newcomer's first): they teach no face height, and a
                track made of them starts afresh at its first refined reading. None: none.

        Returns:
            (K, 3) float64 metres: K = 1 for ``"nearest"``, K >= 1 for ``"all"``.
        """
        e = np.asarray(eyes, np.float64).reshape(-1, 3)
        b = np.asarray(boxes, np.float64).reshape(-1, 4)
        if pose is not None and len(pose.range) != len(e):
            raise ValueError(f"pose has {len(pose.range)} faces, eyes {len(e)}")
        rough = np.zeros(len(e), bool) if coarse is None else np.asarray(coarse, bool).reshape(-1)
        if len(rough) != len(e):
            raise ValueError(f"coarse has {len(rough)} faces, eyes {len(e)}")
        if not self.config.face_height:
            pose = None
        self._match(e, b, float(t), pose, rough)
        one = self._nearest(float(t))
        if self.config.faces == "all" and self.tracks:
            ordered = sorted(self.tracks, key=lambda tr: float(np.linalg.norm(tr.eye)))
            return np.asarray([tr.eye for tr in ordered], np.float64)
        return one[None, :]
