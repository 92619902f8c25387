"""Where a live frame changed: the full-resolution search looks there before its round.

:class:`~viewcomp.rt.track.live_faces.LiveFaces` searches one tile of the frame at full
resolution per frame, in turn, for the faces too small for its half-resolution search (a
viewer 2.5-3.5 m from a 90-degree 720p webcam), so a far newcomer waits for its tile: up to a
round of tiles. Someone who walks or steps into view changes the frame where they are.

:class:`Changes` keeps a running background of the frame shrunk to cells of ``cell`` pixels
(grey, each cell's mean), updated by ``rate`` per frame, and marks the cells whose level moved
more than ``level`` grey levels from it, after the frame's common shift (the camera's
exposure, the room's light) is taken out (the median of all cells' changes). Averaged over a
cell, a webcam's noise is a fraction of a level; a face against a wall is tens of levels.
:meth:`Changes.region` places a search region over the largest group of changed cells that
the faces already known do not explain (a face's cells and those below it: its body), with
the group's top a quarter down the region: a face is at the top of what moves.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

CELL = 16  # frame pixels per cell side
# The background's update per frame: half the way to each new frame, so a change stays
# marked for two or three frames (a face tens of levels off its background) and the place
# someone left is background again as soon (a slower background would keep a departed
# viewer's ghost, the largest change in view, for seconds).
RATE = 0.5
LEVEL = 10.0  # grey levels (0-255): the least change of a cell's mean that counts
MIN_CELLS = 2  # changed cells a group needs (a face 3 m away covers about 3 x 3 cells)
# A known face explains the changes within BODY face widths each side of its centre, from
# half a face above it to the frame's bottom (its head and body moving).
BODY = 1.5


class Changes:
    """A live camera's changed cells (the module's description): :meth:`update` once per
    frame, then :meth:`region`."""

    def __init__(
        self,
        cell: int = CELL,
        rate: float = RATE,
        level: float = LEVEL,
        min_cells: int = MIN_CELLS,
    ) -> None:
        if not (cell >= 1 and 0.0 < rate <= 1.0 and level > 0.0 and min_cells >= 1):
            raise ValueError(
                "need cell >= 1, 0 < rate <= 1, level > 0, min_cells >= 1; got "
                f"{cell}, {rate}, {level}, {min_cells}"
            )
        self.cell, self.rate, self.level, self.min_cells = cell, rate, level, min_cells
        self._back: np.ndarray | None = None
        self._frame_size = (0, 0)
        # (rows, columns) of cells, the last frame's
        self.changed: np.ndarray = np.zeros((0, 0), bool)

    def update(self, image: np.ndarray) -> None:
        """Takes the next frame ((h, w, 3) uint8 BGR or (h, w) grey): marks its changed cells
        (none on the first frame, or one of another size) and updates the background."""
        grey = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
        h, w = grey.shape
        size = (max(1, w // self.cell), max(1, h // self.cell))
        small = cv2.resize(grey, size, interpolation=cv2.INTER_AREA).astype(np.float32)
        if self._back is None or self._frame_size != (w, h):
            self._back, self._frame_size = small, (w, h)
            self.changed = np.zeros(small.shape, bool)
            return
        d = small - self._back
        self.changed = np.abs(d - np.median(d)) > self.level
        cv2.accumulateWeighted(small, self._back, self.rate)

    def region(self, size: tuple[int, int], known: np.ndarray) -> tuple[int, int, int, int] | None:
        """(x0, y0, w, h) frame pixels: a region ``size`` (w, h) within the frame over the
        largest group of the last frame's changed cells (8-connected) that ``known`` ((K, 4)
        face boxes x, y, w, h pixels) do not explain, horizontally centred on the group's
        top row, that row a quarter of the region's height from its top; None where no group
        has ``min_cells`` cells."""
        if not self.changed.any():
            return None
        w, h = self._frame_size
        rows, cols = self.changed.shape
        sx, sy = w / cols, h / rows
        free = self.changed.copy()
        for x, y, bw, bh in np.asarray(known, np.float64).reshape(-1, 4):
            cx = x + bw / 2.0
            c0 = max(0, math.floor((cx - BODY * bw) / sx))
            c1 = max(0, math.ceil((cx + BODY * bw) / sx))
            r0 = max(0, math.floor((y - bh / 2.0) / sy))
            free[r0:, c0:c1] = False
        groups = cv2.connectedComponentsWithStats(free.astype(np.uint8), connectivity=8)
        n, labels, stats, _ = groups
        if n <= 1:
            return None
        k = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
        if stats[k, cv2.CC_STAT_AREA] < self.min_cells:
            return None
        top = int(stats[k, cv2.CC_STAT_TOP])
        cx = (float(np.mean(np.flatnonzero(labels[top] == k))) + 0.5) * sx
        rw, rh = min(size[0], w), min(size[1], h)
        x0 = int(np.clip(round(cx - rw / 2.0), 0, w - rw))
        y0 = int(np.clip(round(top * sy - rh / 4.0), 0, h - rh))
        return (x0, y0, rw, rh)
