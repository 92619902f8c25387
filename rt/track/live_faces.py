"""YuNet for a live camera: little work per frame, so a new face reaches the player soon.

Searching a whole 1280x720 frame at full resolution is the tracker's largest cost (about
25-30 ms on an idle core, several times that on a busy machine); done on every frame, each
frame waits for it. :class:`LiveFaces` spreads that search over frames:

- every frame is searched at ``scale`` (0.5: a quarter of the pixels), which finds every face
  up to about 2 m from a 90-degree 720p webcam at once; the faces found are refined in a crop
  at full resolution as small faces always are (:meth:`YuNetDetector.detect`), but for
  newcomers (below);
- one of ``TILES`` overlapping tiles of the frame is also searched at full resolution, the
  next tile the next time (:func:`tiles`): every frame while nobody is in view, every
  ``TRACKING_EVERY``-th frame while faces are followed. A far newcomer the half-resolution
  search misses is found within one round of the tiles (4 frames into an empty room), and no
  frame pays for the whole frame at full resolution;
- where the frame changed away from the faces known (someone walked or stepped in:
  :class:`~viewcomp.rt.track.changes.Changes`), a region of a quarter of a tile's pixels is
  searched enlarged twice (``CHANGE_SCALE``: a tile's cost) instead of the round's next
  tile, so a far newcomer is found in the first frame that searches one, also one that
  the full-resolution search misses (2.5-3.4 m away with a hand over mouth and chin:
  YuNet needs the face larger); a region searched in vain gives the next search back to
  the round and is looked at less and less often
  (:class:`~viewcomp.rt.track.refusals.Refusals`), so a flickering screen in view, or
  someone with their face turned away, does not stop it;
- a face, once found (by either search), is followed frame by frame in a crop around where
  it was (:meth:`YuNetDetector.refine`, at full resolution) whenever the searches miss it,
  until a crop no longer finds it;
- a small face the searches score under the threshold is looked at again in its crop
  (``YuNetConfig.candidate``); where the crop refused one, less and less often
  (:class:`~viewcomp.rt.track.refusals.Refusals`: a pattern of the room taken for a face
  on every frame would otherwise cost a crop on every frame);
- a newcomer's first reading is the search's own: its refinement crop (about 0.7 megapixels,
  more than the half frame and a tile together) waits for its second frame, and a frame that
  found a newcomer leaves its tile to the next one, so the first eye reaches the player about
  a frame's work sooner. A newcomer the half-resolution search scores under the threshold
  (about 2-2.5 m away) is looked at again in a crop at the frame's own resolution first (a
  tenth of the refinement crop's pixels), and kept with that reading where it is a face
  there. That reading is marked ``coarse`` (the tracker takes no face height
  from it, knows the face's next reading by its box and starts afresh from it): newcomers at
  0.8-3.5 m, 60-120 degrees, are within 10 cm and 10 % in about 80 % of first readings
  (distance error median 6 %, at most 20 %) against 97 % refined (docs/BENCHMARKS.md).
  Where a crop refused a face the search scored just over the threshold (a picture taken for
  a face: ``YuNetConfig.sure``), a newcomer scored so is checked in its crop first, so such
  a picture is published once, for the tracker's hold, not each time the tiles reach it.

All of it runs in the caller's thread and the work per frame is bounded. (A worker thread
searching whole frames back to back took 200-400 ms a search with one of two cores busy, so
a far newcomer waited 0.4-0.8 s, and it competed with every frame's own search; see
docs/BENCHMARKS.md.) Files processed as fast as possible keep the whole-frame
search on every frame (reproducible output): see ``background_search`` of
:class:`viewcomp.rt.track.run.TrackOptions`.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from viewcomp.calib.world.rig import Device
from viewcomp.rt.track.boxes import overlaps
from viewcomp.rt.track.changes import Changes
from viewcomp.rt.track.refusals import Refusals
from viewcomp.rt.track.yunet import Faces, YuNetConfig, YuNetDetector

SCALE = 0.5  # the per-frame search's resize factor
TILES = (2, 2)  # the full-resolution search's tiles across and down, one searched per frame
# Tiles overlap by this much (pixels): any face box up to this size lies wholly in one tile;
# the half-resolution search finds the larger (nearer) ones.
OVERLAP = 96
# While faces are followed, a tile is searched every this many frames (each followed face
# costs a full-resolution crop per frame already); with nobody in view, every frame.
TRACKING_EVERY = 3
# Where the frame changed, a region 1 / CHANGE_SCALE of a tile's width and height is searched
# enlarged by CHANGE_SCALE: the network's input is a tile's, and a face half the size the
# tiles need is found (a far one partly covered).
CHANGE_SCALE = 2.0


def tiles(
    width: int, height: int, across: int, down: int, overlap: int
) -> list[tuple[int, int, int, int]]:
    """(x0, y0, w, h) of ``across`` x ``down`` tiles of one size covering a width x height
    frame, neighbours overlapping by at least ``overlap`` pixels, row by row."""
    tw = min(width, math.ceil(width / across) + overlap)
    th = min(height, math.ceil(height / down) + overlap)
    xs = np.linspace(0, width - tw, across).round().astype(int) if across > 1 else [0]
    ys = np.linspace(0, height - th, down).round().astype(int) if down > 1 else [0]
    return [(int(x), int(y), tw, th) for y in ys for x in xs]


class LiveFaces:
    """The faces of each live frame (the module's description); ``detect`` as
    :meth:`YuNetDetector.detect`."""

    def __init__(
        self, config: YuNetConfig | None = None, scale: float = SCALE, device: Device | None = None
    ) -> None:
        self.config = config or YuNetConfig()
        self.scale = scale
        # where the second look refused a candidate, in either search (the frame's pixels)
        self.refusals = Refusals()
        self.frame_detector = YuNetDetector(self.config, device=device, refusals=self.refusals)
        # networks of their own: the tiles keep one input size, the half frame another,
        # the enlarged change regions a third
        self.tile_detector = YuNetDetector(self.config, device=device, refusals=self.refusals)
        self.change_detector = YuNetDetector(self.config, device=device, refusals=self.refusals)
        self.path = self.frame_detector.path
        self._followed = np.zeros((0, 4))  # boxes of the last frame's faces
        self.tiles_searched = 0
        # where the frame changed, away from the faces known: searched before the tiles'
        # round; a region searched there in vain is looked at less and less often, and
        # gives the next search to the round (a person whose face is turned away, walking,
        # would otherwise hold the round up for as long as they move)
        self.changes = Changes()
        self.vain = Refusals()
        self.changes_searched = 0
        self._round_next = False
        self._frames = 0
        self._grid: tuple[tuple[int, int], list[tuple[int, int, int, int]]] = ((0, 0), [])

    def detect(self, image: np.ndarray, follow: np.ndarray | None = None) -> Faces:
        """The faces in ``image`` ((h, w, 3) uint8 BGR or (h, w) grey): the half-resolution
        search's, then the tile's new ones, then the followed ones; ``follow`` (K, 4): boxes
        of faces tracked so far, followed as the last frame's faces are. A newcomer (a face
        overlapping none of these boxes nor the last frame's faces by more than 0.3 IoU)
        keeps the search's own landmarks (``Faces.coarse`` where it is small); a frame
        that found one leaves its tile to the next frame."""
        if image.ndim == 2:  # grey: the crops are searched as colour frames are
            image = cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
        if follow is not None:
            self._followed = np.concatenate([self._followed, np.reshape(follow, (-1, 4))])
        known = self._followed
        self.refusals.tick()
        self.vain.tick()
        self.changes.update(image)
        faces = self.frame_detector.detect(image, self.scale, refine_near=known)
        self._frames += 1
        due = not len(known) or self._frames % TRACKING_EVERY == 0
        newcomer = any(not overlaps(b, known) for b in faces.boxes)
        if due and not newcomer:
            h, w = image.shape[:2]
            if self._grid[0] != (w, h):  # the frame's size: the tiles are computed once
                self._grid = ((w, h), tiles(w, h, *TILES, OVERLAP))
            grid = self._grid[1]
            explained = np.concatenate([known, faces.boxes])
            size = (round(grid[0][2] / CHANGE_SCALE), round(grid[0][3] / CHANGE_SCALE))
            changed = None if self._round_next else self.changes.region(size, explained)
            if changed is not None and self.vain.due(place := np.asarray(changed, np.float64)):
                found = self.change_detector.search_region(
                    image, changed, faces.boxes, known, scale=CHANGE_SCALE
                )
                self.vain.found(place) if len(found) else self.vain.refused(place)
                self._round_next = not len(found)
                self.changes_searched += 1
            else:
                region = grid[self.tiles_searched % len(grid)]
                found = self.tile_detector.search_region(image, region, faces.boxes, known)
                self.tiles_searched += 1
                self._round_next = False
            faces = faces.extended(found)
        more = Faces.from_rows(self.frame_detector.follow(image, known, faces.boxes))
        # next frame, every face of this one is followed in a crop if the searches miss it
        # (a viewer walking away beyond the half-resolution search's reach)
        self._followed = np.concatenate([faces.boxes, more.boxes])
        return faces.extended(more)
