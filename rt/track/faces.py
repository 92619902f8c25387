"""The fallback face detector (``--detector cascade``): OpenCV's LBP frontal-face cascade.

YuNet (:mod:`viewcomp.rt.track.yunet`, its model shipped in the package) is the detector;
this one is kept for where it cannot run, and its distance comes from the box's size. Which
cascade, and why: the installed OpenCV (opencv-contrib-python-headless 5.x) no longer ships
the Haar cascades (``cv2.data`` holds no XML files); scikit-image ships OpenCV's LBP
frontal-face cascade (``skimage.data.lbp_frontal_face_cascade_filename()``, trained by
OpenCV on 24x24 windows); ``cv2.CascadeClassifier`` runs it once a misspelt tag of that
copy (``featuhreParams``) is corrected, in memory. LBP cascades are integer features, about
as accurate on frontal faces as the Haar ones and several times faster.

False faces: a box needs ``min_neighbors`` overlapping hits, local contrast
(:func:`detail_of`: LBP ignores contrast, so noise on a flat wall can look like a face) and,
in a colour frame, a middle that is mostly skin-toned (:func:`skin_share`).

Speed: the search is limited to the face sizes that the distance range [near, far] allows
(:func:`size_range`), and once a face is found the next frames search only around it
(a window of ``roi_margin`` face widths each side, sizes within a factor ``roi_scale``), with
a full search every ``full_every`` frames for newcomers. Every box is then searched again
in its window on a few shifted size grids and the median taken (:meth:`FaceDetector.refine`),
which makes the size, hence the distance, finer than the cascade's size steps.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import cv2
import numpy as np

from viewcomp.calib.errors import DetectorError

# Below this width the 24x24 cascade misses most faces; the detector upsamples nothing.
MIN_FACE_PX = 24


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

    ``scale_factor`` (> 1): step between searched face sizes, and ``min_neighbors``: the
    overlapping hits a face needs (higher: fewer false faces, more misses), where a face is
    looked for again (:meth:`FaceDetector.refine`); ``full_scale_factor`` and
    ``full_min_neighbors``: the same for the full-frame search, which only proposes
    candidates for the refinement (coarser steps and fewer hits: fast, and a missed far face
    costs more than a false candidate). ``min_px``/``max_px``: box widths searched, pixels;
    ``full_every``: frames between full-frame searches while faces are tracked (1: always
    full); ``roi_margin``: the window around a tracked face, in face widths each side;
    ``roi_scale``: sizes searched there, a factor either way; ``dither``: searches of that
    window on shifted size grids; ``skin``: the share (0..1) of skin-toned pixels a colour
    box needs (:func:`skin_share`; 0: no check); ``detail``: the local contrast a box needs,
    grey levels (:func:`detail_of`; 0: no check).
    """

    scale_factor: float = 1.1
    min_neighbors: int = 3
    full_scale_factor: float = 1.2
    full_min_neighbors: int = 2
    min_px: int = MIN_FACE_PX
    max_px: int = 400
    full_every: int = 15
    roi_margin: float = 1.0
    roi_scale: float = 1.4
    dither: int = 4
    skin: float = 0.5
    detail: float = 8.0


class FaceDetector:
    """Finds frontal faces in 8-bit frames. Not thread-safe: one per thread."""

    def __init__(self, config: DetectorConfig | None = None) -> None:
        self.config = config or DetectorConfig()
        self.cascade = load_cascade()
        self._frames = 0
        self.full_searches = 0

    def _search(
        self, gray: np.ndarray, lo: float, hi: float, coarse: bool = False
    ) -> tuple[np.ndarray, np.ndarray]:
        """Boxes (N, 4) and their overlapping-hit counts (N,) for widths lo..hi pixels;
        ``coarse``: the full-frame search's settings (``full_scale_factor``,
        ``full_min_neighbors``)."""
        c = self.config
        lo_i = max(MIN_FACE_PX, int(lo))
        hi_i = max(lo_i + 1, int(np.ceil(hi)))
        found, hits = self.cascade.detectMultiScale2(
            gray,
            scaleFactor=c.full_scale_factor if coarse else c.scale_factor,
            minNeighbors=c.full_min_neighbors if coarse else c.min_neighbors,
            minSize=(lo_i, lo_i),
            maxSize=(hi_i, hi_i),
        )
        return np.asarray(found, np.float64).reshape(-1, 4), np.asarray(hits, np.float64).ravel()

    def refine(self, gray: np.ndarray, box: np.ndarray) -> tuple[np.ndarray, float] | None:
        """The face near ``box`` (x, y, w, h), searched again in a window around it, and its
        hit count summed over the searches; None when it is not found again.

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
        found, score = [], 0.0
        for k in range(max(1, c.dither)):
            r = c.scale_factor ** (k / max(1, c.dither))
            img = roi if k == 0 else cv2.resize(roi, None, fx=r, fy=r)
            lo = max(c.min_px * r, bw * r / c.roi_scale)
            hi = min(c.max_px * r, bw * r * c.roi_scale)
            b, hits = self._search(img, lo, hi)
            if len(b):
                b = b / r
                off = np.hypot(*(b[:, :2] + b[:, 2:] / 2 - centre).T)
                i = int(np.argmin(off))
                if off[i] < bw:
                    found.append(b[i])
                    score += float(hits[i])
        if not found:
            return None
        return np.median(np.asarray(found), axis=0) + np.array([x0, y0, 0.0, 0.0]), score

    def candidates(self, frame: np.ndarray) -> np.ndarray:
        """The full-frame search alone: (N, 4) candidate boxes for :meth:`detect`'s hints
        (unrefined, unchecked). Safe on another thread with another FaceDetector."""
        gray = frame if frame.ndim == 2 else cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
        c = self.config
        return self._search(gray, c.min_px, c.max_px, coarse=True)[0]

    def detect(
        self,
        frame: np.ndarray,
        hints: np.ndarray | None = None,
        gray: np.ndarray | None = None,
        periodic: bool = True,
    ) -> np.ndarray:
        """Faces in ``frame``.

        Args:
            frame: (h, w, 3) uint8 BGR (OpenCV's order) or (h, w) uint8 gray.
            hints: (K, 4) boxes (x, y, w, h) where faces were last seen, or None; with hints
                only those neighbourhoods are searched, except every ``full_every``-th frame
                (with ``periodic``), every frame without hints and a frame where a hinted
                face is not found again, when the whole frame is.
            gray: ``frame`` in grey, if the caller has it already.
            periodic: False when another thread runs the periodic full searches
                (:meth:`candidates`) and passes what they find as hints.

        Returns:
            (N, 4) float64 boxes (x, y, w, h), pixels, top-left corner, strongest first; may
            be empty. Every box is refined (:meth:`refine`), so a face's size does not depend
            on which kind of search found it; of boxes that overlap (one's centre inside the
            other) the one with more cascade hits is kept.
        """
        if gray is None:
            gray = frame if frame.ndim == 2 else cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
        c = self.config
        self._frames += 1
        candidates = np.zeros((0, 4)) if hints is None else np.asarray(hints, np.float64)
        candidates = candidates.reshape(-1, 4)
        due = periodic and (c.full_every <= 1 or self._frames % c.full_every == 0)
        full = len(candidates) == 0 or due
        boxes: list[np.ndarray] = []
        scores: list[float] = []
        while True:
            if full:
                self.full_searches += 1
                candidates = np.concatenate(
                    [candidates, self._search(gray, c.min_px, c.max_px, coarse=True)[0]]
                )
            lost = False
            boxes, scores = [], []
            for b in candidates:
                r = self.refine(gray, b)
                if r is None:
                    lost = True
                    continue
                if c.skin > 0 and frame.ndim == 3 and skin_share(frame, r[0]) < c.skin:
                    continue
                if c.detail > 0 and detail_of(gray, r[0]) < c.detail:
                    continue
                boxes.append(r[0])
                scores.append(r[1])
            if full or not lost:
                break
            full = True  # a tracked face was not found near where it was: search everywhere
        return _dedupe(np.asarray(boxes, np.float64).reshape(-1, 4), np.asarray(scores))


def _dedupe(boxes: np.ndarray, scores: np.ndarray) -> np.ndarray:
    """Boxes by decreasing score, without those whose centre lies inside a box kept before
    (the same face found twice, or a larger false box around a face)."""
    keep: list[np.ndarray] = []
    for i in np.argsort(-scores, kind="stable"):
        b = boxes[i]
        cx, cy = b[0] + b[2] / 2, b[1] + b[3] / 2
        inside = any(k[0] <= cx <= k[0] + k[2] and k[1] <= cy <= k[1] + k[3] for k in keep)
        contains = any(
            b[0] <= k[0] + k[2] / 2 <= b[0] + b[2] and b[1] <= k[1] + k[3] / 2 <= b[1] + b[3]
            for k in keep
        )
        if not (inside or contains):
            keep.append(b)
    return np.asarray(keep, np.float64).reshape(-1, 4)


def detail_of(gray: np.ndarray, box: np.ndarray) -> float:
    """Local contrast in ``box`` (x, y, w, h) of a uint8 ``gray`` frame, in grey levels: the
    box resampled to the cascade's 24x24 (area average), minus its Gaussian blur (sigma 3),
    the standard deviation over the middle 16x16.

    LBP features compare neighbouring pixels without their contrast, so sensor noise on a
    flat, smoothly lit wall can pass the cascade; a face has eyes, brows and a mouth (25-45
    levels on the simulated walk at 1..3 m), a flat wall about 1.
    """
    x, y, w, h = (int(np.rint(v)) for v in box)
    crop = gray[max(0, y) : max(0, y + h), max(0, x) : max(0, x + w)]
    if crop.shape[0] < 4 or crop.shape[1] < 4:
        return 0.0
    small = cv2.resize(crop.astype(np.float32), (24, 24), interpolation=cv2.INTER_AREA)
    high = small - cv2.GaussianBlur(small, (0, 0), 3.0)
    return float(high[4:20, 4:20].std())


def skin_share(frame: np.ndarray, box: np.ndarray) -> float:
    """The share (0..1) of skin-toned pixels in the middle half of ``box`` (x, y, w, h) of a
    BGR uint8 ``frame``: YCrCb with 133 <= Cr <= 173 and 77 <= Cb <= 127 (Chai and Ngan,
    1999). A grey middle (a monochrome or infrared camera) counts as skin: 1.0.

    The cascade alone also finds "faces" in wallpaper and shelves; those rarely have skin's
    chroma, so the check removes most false viewers at the cost of nothing on real faces.
    """
    x, y, w, h = (int(np.rint(v)) for v in box)
    crop = frame[
        max(0, y + h // 4) : max(0, y + 3 * h // 4), max(0, x + w // 4) : max(0, x + 3 * w // 4)
    ]
    if crop.size == 0:
        return 0.0
    chans = crop.reshape(-1, 3).astype(np.int16)
    if (
        int(np.abs(chans[:, 0] - chans[:, 1]).max()) <= 2
        and int(np.abs(chans[:, 1] - chans[:, 2]).max()) <= 2
    ):
        return 1.0
    ycc = cv2.cvtColor(crop, cv2.COLOR_BGR2YCrCb)
    cr, cb = ycc[..., 1], ycc[..., 2]
    return float(np.mean((cr >= 133) & (cr <= 173) & (cb >= 77) & (cb <= 127)))
