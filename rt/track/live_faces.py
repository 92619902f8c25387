"""YuNet for a live camera: little work per frame, so a new face reaches the player soon.

Searching a whole 1280x720 frame at full resolution is the tracker's largest cost (about
25-30 ms on an idle core, several times that on a busy machine); done on every frame, each
frame waits for it. :class:`LiveFaces` splits the work:

- every frame is searched at ``scale`` (0.5: a quarter of the pixels), which finds every face
  up to about 2 m from a 90-degree 720p webcam at once; the faces found are refined in a crop
  at full resolution as small faces always are (:meth:`YuNetDetector.detect`);
- the whole frame at full resolution is searched on a worker thread, one search at a time,
  each on the newest frame: it finds the far faces the half-resolution search misses;
- a face, once found (by either search), is followed frame by frame in a crop around where
  it was (:meth:`YuNetDetector.refine`, at full resolution) whenever the half-resolution
  search misses it, until a crop no longer finds it.

A far newcomer therefore appears one full search later than a near one. Files processed as
fast as possible keep the whole-frame search on every frame (reproducible output): see
``background_search`` of :class:`viewcomp.rt.track.run.TrackOptions`.
"""

from __future__ import annotations

from concurrent.futures import Future, ThreadPoolExecutor

import cv2
import numpy as np

from viewcomp.rt.track.yunet import Faces, YuNetConfig, YuNetDetector

SCALE = 0.5  # the per-frame search's resize factor


class LiveFaces:
    """The faces of each live frame (the module's description); ``detect`` as
    :meth:`YuNetDetector.detect`. Call :meth:`close` to end the worker thread."""

    def __init__(self, config: YuNetConfig | None = None, scale: float = SCALE) -> None:
        self.config = config or YuNetConfig()
        self.scale = scale
        self.frame_detector = YuNetDetector(self.config)  # this thread's
        self.full_detector = YuNetDetector(self.config)  # the worker's (not thread-safe)
        self.path = self.frame_detector.path
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="viewcomp-faces")
        self._pending: Future[Faces] | None = None
        self._followed = np.zeros((0, 4))  # boxes of far faces followed in crops
        self.full_searches = 0

    def detect(self, image: np.ndarray, follow: np.ndarray | None = None) -> Faces:
        """The faces in ``image`` ((h, w, 3) uint8 BGR or (h, w) grey), the near ones first,
        then the followed far ones; ``follow`` (K, 4): boxes of faces tracked so far, followed
        as the last frame's faces are."""
        if image.ndim == 2:  # grey: the crops are searched as colour frames are
            image = cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
        faces = self.frame_detector.detect(image, self.scale)
        if self._pending is not None and self._pending.done():
            found = self._pending.result()
            self._pending = None
            self._followed = np.concatenate([self._followed, found.boxes])
        if self._pending is None:
            self._pending = self._pool.submit(self.full_detector.detect, image)
            self.full_searches += 1
        if follow is not None:
            self._followed = np.concatenate([self._followed, np.reshape(follow, (-1, 4))])
        more = self.frame_detector.follow(image, self._followed, faces.boxes)
        # next frame, every face of this one is followed in a crop if its search misses it
        # (a viewer walking away beyond the half-resolution search's reach)
        self._followed = np.concatenate([faces.boxes, more[:, :4]])
        return faces.extended(more)

    def close(self) -> None:
        """End the worker thread (after the search in progress)."""
        self._pool.shutdown(wait=True, cancel_futures=True)
