"""Face detection in the tracking camera's frames: OpenCV's LBP frontal-face cascade.

Which detector, and why: the installed OpenCV (opencv-contrib-python-headless 5.x) no longer
ships the Haar cascades (``cv2.data`` holds no XML files), and ``cv2.FaceDetectorYN`` (YuNet)
needs an ONNX model that no installed package carries. scikit-image ships OpenCV's LBP
frontal-face cascade (``skimage.data.lbp_frontal_face_cascade_filename()``, trained by
OpenCV on 24x24 windows); ``cv2.CascadeClassifier`` runs it once a misspelt tag of that
copy (``featuhreParams``) is corrected, in memory. LBP cascades are integer features, about
as accurate on frontal faces as the Haar ones and several times faster.

Speed: the search is limited to the face sizes that the distance range [near, far] allows
(:func:`size_range`), and once a face is found the next frames search only around it
(a window of ``roi_margin`` face widths each side, sizes within a factor ``roi_scale``), with
a full search every ``full_every`` frames for newcomers.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import cv2
import numpy as np

# Below this width the 24x24 cascade misses most faces; the detector upsamples nothing.
MIN_FACE_PX = 24


class DetectorError(RuntimeError):
    """The face model cannot be loaded; the message says what is missing."""


@functools.lru_cache(maxsize=1)
def _cascade_text() -> str:
    try:
        from skimage.data import lbp_frontal_face_cascade_filename
    except ImportError as exc:  # pragma: no cover - scikit-image is a dependency
        raise DetectorError(f"scikit-image is needed for its face cascade: {exc}") from None
    with open(lbp_frontal_face_cascade_filename(), encoding="utf-8") as f:
        return f.read().replace("featuhreParams", "featureParams")


def load_cascade() -> cv2.CascadeClassifier:
    """A new ``cv2.CascadeClassifier`` holding the LBP frontal-face cascade (24x24 window).

    Raises:
        DetectorError: OpenCV cannot read the cascade.
    """
    fs = cv2.FileStorage(_cascade_text(), cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY)
    cascade = cv2.CascadeClassifier()
    if not cascade.read(fs.getFirstTopLevelNode()) or cascade.empty():
        raise DetectorError("OpenCV could not read scikit-image's LBP face cascade")
    return cascade


def size_range(focal_px: float, face_width: float, near: float, far: float) -> tuple[int, int]:
    """Box widths (min, max) in pixels for faces between ``near`` and ``far`` metres (depth
    along the camera's axis), with 15 % slack; the minimum is at least MIN_FACE_PX."""
    lo = max(MIN_FACE_PX, int(focal_px * face_width / far / 1.15))
    hi = max(lo + 1, int(np.ceil(focal_px * face_width / near * 1.15)))
    return lo, hi


@dataclass
class DetectorConfig:
    """How to search.

    ``scale_factor`` (> 1): step between searched face sizes; ``min_neighbors``: overlapping
    hits a face needs (higher: fewer false faces, more misses); ``min_px``/``max_px``: box
    widths searched, pixels; ``full_every``: frames between full-frame searches while faces
    are tracked (1: always full); ``roi_margin``: the window around a tracked face, in face
    widths each side; ``roi_scale``: sizes searched there, a factor either way; ``dither``:
    searches of that window on shifted size grids (:meth:`FaceDetector.refine`).
    """

    scale_factor: float = 1.1
    min_neighbors: int = 3
    min_px: int = MIN_FACE_PX
    max_px: int = 400
    full_every: int = 15
    roi_margin: float = 1.0
    roi_scale: float = 1.4
    dither: int = 4


class FaceDetector:
    """Finds frontal faces in 8-bit frames. Not thread-safe: one per thread."""

    def __init__(self, config: DetectorConfig | None = None) -> None:
        self.config = config or DetectorConfig()
        self.cascade = load_cascade()
        self._frames = 0
        self.full_searches = 0

    def _search(self, gray: np.ndarray, lo: float, hi: float) -> np.ndarray:
        c = self.config
        lo_i = max(MIN_FACE_PX, int(lo))
        hi_i = max(lo_i + 1, int(np.ceil(hi)))
        found = self.cascade.detectMultiScale(
            gray,
            scaleFactor=c.scale_factor,
            minNeighbors=c.min_neighbors,
            minSize=(lo_i, lo_i),
            maxSize=(hi_i, hi_i),
        )
        return np.asarray(found, np.float64).reshape(-1, 4)

    def refine(self, gray: np.ndarray, box: np.ndarray) -> np.ndarray | None:
        """The face near ``box`` (x, y, w, h), searched again in a window around it, or None.

        The window is searched ``dither`` times, each resized by scale_factor^(k / dither):
        the cascade only tries sizes on a geometric grid, and the median over shifted grids
        is a finer size (hence distance) than one grid gives.
        """
        c = self.config
        h, w = gray.shape[:2]
        x, y, bw = float(box[0]), float(box[1]), float(box[2])
        m = c.roi_margin * bw
        x0, y0 = max(0, int(x - m)), max(0, int(y - m))
        x1, y1 = min(w, int(np.ceil(x + bw + m))), min(h, int(np.ceil(y + bw + m)))
        if x1 - x0 < MIN_FACE_PX or y1 - y0 < MIN_FACE_PX:
            return None
        roi = gray[y0:y1, x0:x1]
        centre = np.array([x - x0 + bw / 2, y - y0 + bw / 2])
        found = []
        for k in range(max(1, c.dither)):
            r = c.scale_factor ** (k / max(1, c.dither))
            img = roi if k == 0 else cv2.resize(roi, None, fx=r, fy=r)
            lo = max(c.min_px * r, bw * r / c.roi_scale)
            hi = min(c.max_px * r, bw * r * c.roi_scale)
            b = self._search(img, lo, hi) / r
            if len(b):
                off = b[:, :2] + b[:, 2:] / 2 - centre
                nearest = b[np.argmin(np.hypot(off[:, 0], off[:, 1]))]
                if np.hypot(*(nearest[:2] + nearest[2:] / 2 - centre)) < bw:
                    found.append(nearest)
        if not found:
            return None
        return np.median(np.asarray(found), axis=0) + np.array([x0, y0, 0.0, 0.0])

    def detect(self, frame: np.ndarray, hints: np.ndarray | None = None) -> np.ndarray:
        """Faces in ``frame``.

        Args:
            frame: (h, w, 3) uint8 BGR (OpenCV's order) or (h, w) uint8 gray.
            hints: (K, 4) boxes (x, y, w, h) where faces were last seen, or None; with hints
                only those neighbourhoods are searched, except every ``full_every``-th frame
                (and every frame without hints), when the whole frame is.

        Returns:
            (N, 4) float64 boxes (x, y, w, h), pixels, top-left corner; may be empty. Every
            box is refined (:meth:`refine`), so a face's size does not depend on which kind
            of search found it.
        """
        gray = frame if frame.ndim == 2 else cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
        c = self.config
        self._frames += 1
        candidates = np.zeros((0, 4)) if hints is None else np.asarray(hints, np.float64)
        candidates = candidates.reshape(-1, 4)
        if len(candidates) == 0 or c.full_every <= 1 or self._frames % c.full_every == 0:
            self.full_searches += 1
            full = self._search(gray, c.min_px, c.max_px)
            candidates = _dedupe(np.concatenate([candidates, full]))
        out = [self.refine(gray, b) for b in candidates]
        return _dedupe(np.asarray([b for b in out if b is not None], np.float64).reshape(-1, 4))


def _dedupe(boxes: np.ndarray) -> np.ndarray:
    """Drop boxes whose centre lies inside an earlier, larger-or-equal box (overlapping
    searches find a face twice); the larger box is kept."""
    keep: list[np.ndarray] = []
    for b in boxes[np.argsort(-boxes[:, 2], kind="stable")] if len(boxes) else boxes:
        cx, cy = b[0] + b[2] / 2, b[1] + b[3] / 2
        if not any(k[0] <= cx <= k[0] + k[2] and k[1] <= cy <= k[1] + k[3] for k in keep):
            keep.append(b)
    return np.asarray(keep, np.float64).reshape(-1, 4)
