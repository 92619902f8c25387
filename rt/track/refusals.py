"""Where a second look found no face: such a place is looked at less and less often.

YuNet's search keeps a small face it scores under the threshold only if the face's
refinement crop finds it (``candidate`` of :class:`~viewcomp.rt.track.yunet.YuNetConfig`),
and one it scores just over it only if the crop finds it both as it is and mirrored
(``sure``); a live newcomer scored so is checked only where a refusal is remembered.
A pattern of the room that the search takes for such a face on every frame, and that the
crop refuses every time, would cost a crop (a few tens of milliseconds of the frame's work)
on every frame for as long as it is in view: the half-resolution search of
:class:`~viewcomp.rt.track.live_faces.LiveFaces` offers one on every frame in 6 of the first
60 of the tracking tests' empty rooms (``background`` seeds 100-159).

:class:`Refusals` remembers such places: one refused n times in a row is not looked at for
the next min(2^(n-1), ``max_wait``) frames (1, 2, 4, ... 32), and a candidate there is left
out meanwhile; a face the crop finds there, or a place offered no more for ``forget`` frames,
is forgotten. A persistent false candidate costs 6 crops in its first 64 frames and then one
a second at 30 frames/s; a real face refused once (a far face behind a hand) is looked at
again two frames later. :class:`~viewcomp.rt.track.live_faces.LiveFaces` keeps a second one
for the regions where the frame changed and a full-resolution search there found no face.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from viewcomp.rt.track.boxes import SAME_FACE, iou

MAX_WAIT = 32  # frames: the longest a refused place is skipped (about 1 s at 30 frames/s)
FORGET = 64  # frames a place is remembered after it was last offered
CAPACITY = 32  # places remembered at most (the oldest offered is dropped first)


@dataclass
class _Place:
    box: np.ndarray  # (4,) x, y, w, h pixels, the latest refused box there
    streak: int  # refusals in a row
    until: int  # the first frame it is looked at again
    offered: int  # the last frame a candidate was there


class Refusals:
    """The places the second look refused (the module's description); boxes x, y, w, h
    pixels of one camera's frames, one :meth:`tick` per frame."""

    def __init__(
        self, max_wait: int = MAX_WAIT, forget: int = FORGET, capacity: int = CAPACITY
    ) -> None:
        if not (max_wait >= 1 and forget >= max_wait and capacity >= 1):
            raise ValueError(
                f"need max_wait >= 1, forget >= max_wait, capacity >= 1; got {max_wait}, "
                f"{forget}, {capacity}"
            )
        self.max_wait, self.forget, self.capacity = max_wait, forget, capacity
        self.frame = 0
        self._places: list[_Place] = []

    def __len__(self) -> int:
        return len(self._places)

    def tick(self) -> None:
        """The next frame; places not offered for ``forget`` frames are forgotten."""
        self.frame += 1
        self._places = [p for p in self._places if self.frame - p.offered <= self.forget]

    def _at(self, box: np.ndarray) -> _Place | None:
        """The remembered place that ``box`` (4,) overlaps most (IoU above
        :data:`~viewcomp.rt.track.boxes.SAME_FACE`), or None."""
        if not self._places:
            return None
        overlap = iou(np.asarray(box, np.float64), np.stack([p.box for p in self._places]))
        i = int(np.argmax(overlap))
        return self._places[i] if overlap[i] > SAME_FACE else None

    def remembers(self, box: np.ndarray) -> bool:
        """Whether a refused place lies at ``box`` (4,) (whether or not its wait is over)."""
        return self._at(box) is not None

    def due(self, box: np.ndarray) -> bool:
        """Whether a candidate at ``box`` (4,) is to be looked at on this frame (no refused
        place there, or its wait is over); a place asked about counts as offered on this
        frame (it is remembered while candidates keep coming there)."""
        place = self._at(box)
        if place is None:
            return True
        place.offered = self.frame
        return self.frame >= place.until

    def refused(self, box: np.ndarray) -> None:
        """The crop found no face at ``box`` (4,) on this frame."""
        place = self._at(box)
        if place is None:
            if len(self._places) >= self.capacity:
                self._places.remove(min(self._places, key=lambda p: p.offered))
            place = _Place(np.zeros(4), 0, 0, self.frame)
            self._places.append(place)
        place.box = np.asarray(box, np.float64).copy()
        place.streak += 1
        place.offered = self.frame
        place.until = self.frame + 1 + min(2 ** (place.streak - 1), self.max_wait)

    def found(self, box: np.ndarray) -> None:
        """The crop found a face at ``box`` (4,): the places it overlaps are forgotten."""
        if not self._places:
            return
        overlap = iou(np.asarray(box, np.float64), np.stack([p.box for p in self._places]))
        self._places = [p for p, o in zip(self._places, overlap, strict=True) if o <= SAME_FACE]
