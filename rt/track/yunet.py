"""Faces and their landmarks: YuNet (``cv2.FaceDetectorYN``) with the model shipped here.

The model (``models/face_detection_yunet_2023mar.onnx``, Apache-2.0, provenance in
``models/README.md``) is checked against its sha256 at every load: a missing or damaged file
is a :class:`~viewcomp.rt.track.faces.DetectorError` naming the file, never a silent fallback.

Per face YuNet gives a box, five landmarks and a score; the landmarks, not the box, are what
:mod:`viewcomp.rt.track.anatomy` turns into an eye position (a box's size depends on the
detector's training, not on the face).
"""

from __future__ import annotations

import hashlib
import logging
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from viewcomp.calib.world.rig import Device
from viewcomp.rt.track.boxes import around, overlaps
from viewcomp.rt.track.faces import DetectorError
from viewcomp.rt.track.noise import relative_noise, smoothed_around, smoothing
from viewcomp.rt.track.rectify import View
from viewcomp.rt.track.refusals import Refusals

log = logging.getLogger(__name__)

MODEL_PATH = Path(__file__).resolve().parent / "models" / "face_detection_yunet_2023mar.onnx"
MODEL_SHA256 = "8f2383e4dd3cfbb4553ea8718107fc0423210dc964f9f4280604804ed2552fa4"
# A refinement crop reaches this many face sizes each side of the face's centre (a tighter
# one reads turns worse).
CONTEXT = 2.0


def check_model(path: str | Path = MODEL_PATH, sha256: str = MODEL_SHA256) -> Path:
    """``path`` if it is the YuNet model whose checksum is ``sha256``.

    Raises:
        DetectorError: the file is missing, unreadable or differs (damaged, truncated or
            another model); the message names the file and how to restore it.
    """
    p = Path(path)
    fix = "reinstall viewcomp (the model ships inside the package), or use --detector cascade"
    try:
        digest = hashlib.sha256(p.read_bytes()).hexdigest()
    except OSError as exc:
        raise DetectorError(f"the face model {p} cannot be read ({exc.strerror}); {fix}") from None
    if digest != sha256:
        raise DetectorError(
            f"the face model {p} is damaged: sha256 {digest}, expected {sha256}; {fix}"
        )
    return p


def cut(box: np.ndarray, region: tuple[int, int, int, int], shape: tuple[int, ...]) -> bool:
    """Whether ``box`` (x, y, w, h pixels) reaches within 4 pixels of an edge of ``region``
    (x0, y0, width, height) that is not the frame's (``shape``: (h, w, ...)): a face there
    may be cut by the region, and its landmarks those of a part of it."""
    x0, y0, rw, rh = region
    fh, fw = shape[:2]
    m = 4.0
    return bool(
        (x0 > 0 and box[0] <= x0 + m)
        or (y0 > 0 and box[1] <= y0 + m)
        or (x0 + rw < fw and box[0] + box[2] >= x0 + rw - m)
        or (y0 + rh < fh and box[1] + box[3] >= y0 + rh - m)
    )


# A landmark's mirror image: the eyes and the mouth corners change sides.
MIRRORED = (1, 0, 2, 4, 3)


def mirrored(rows: np.ndarray, width: int) -> np.ndarray:
    """(M, 15) YuNet rows (box, landmarks, score) of an image ``width`` pixels wide, as they
    lie in the image mirrored left to right (pixel centres at integers): x becomes
    width - 1 - x, a box's left edge is its right one's mirror, and the landmarks keep
    YuNet's order (the eye on the image's left first)."""
    r = np.array(rows, np.float64).reshape(-1, 15)
    r[:, 0] = width - 1 - (r[:, 0] + r[:, 2])
    marks = r[:, 4:14].reshape(-1, 5, 2)[:, MIRRORED]
    marks[..., 0] = width - 1 - marks[..., 0]
    r[:, 4:14] = marks.reshape(-1, 10)
    return r


def mirror_average(row: np.ndarray, match: np.ndarray | None) -> np.ndarray:
    """(15,) ``row``, a face YuNet found in an image, averaged with ``match``, its reading in
    the image mirrored left to right, mirrored back (:func:`mirror_match`); ``row`` itself
    where that found none (None). Box, landmarks and score are each the mean of the two.

    YuNet's landmarks are not mirror-symmetric: a face and its mirror image are read up to
    a pixel or two apart (1.7 pixels with 25 pixels between the eyes), a turn and a range
    that are not there. The mean of a reading and its mirror's leans neither way."""
    return row if match is None else 0.5 * (row + match)


def mirror_match(row: np.ndarray, seen: np.ndarray, width: int) -> np.ndarray | None:
    """(15,) the reading of ``row`` (a face found in an image ``width`` pixels wide) among
    ``seen`` (M, 15, rows found in the image mirrored left to right), mirrored back: the
    one whose box centre lies nearest ``row``'s, None where none lies within 0.3 of its
    box's width."""
    if len(seen) == 0:
        return None
    back = mirrored(seen, width)
    centres = back[:, :2] + back[:, 2:4] / 2
    d = np.hypot(*(centres - (row[:2] + row[2:4] / 2)).T)
    j = int(np.argmin(d))
    return None if d[j] > 0.3 * row[2] else back[j]


def sure_both_ways(row: np.ndarray, match: np.ndarray | None, sure: float) -> bool:
    """Whether a face's reading in its crop, ``row`` (15,), and its reading in the crop
    mirrored, ``match`` (15,; None: not found), score ``sure`` or more on average: a face
    the search is unsure of must be one its enlarged crop is sure of, both ways (a galaxy
    of the Hubble deep field, 0.68 in the search, reads 0.68 and 0.61 in its crop)."""
    return match is not None and (row[14] + match[14]) / 2 >= sure


@dataclass
class Faces:
    """One frame's faces, strongest first.

    ``boxes`` (N, 4) x, y, w, h pixels (top-left corner); ``landmarks`` (N, 5, 2) pixels (x
    right, y down): the eye on the image's left, the eye on the image's right, the nose tip,
    the mouth corner on the image's left, the one on its right; ``scores`` (N,) in 0..1;
    ``coarse`` (N,) bool: the face is small and its landmarks are the search's own, not
    refined in a crop (a live newcomer's first reading: a few times less precise, see
    :class:`~viewcomp.rt.track.live_faces.LiveFaces`).
    """

    boxes: np.ndarray
    landmarks: np.ndarray
    scores: np.ndarray
    coarse: np.ndarray

    def __len__(self) -> int:
        return len(self.scores)

    @staticmethod
    def empty() -> Faces:
        return Faces(np.zeros((0, 4)), np.zeros((0, 5, 2)), np.zeros(0), np.zeros(0, bool))

    @staticmethod
    def from_rows(rows: np.ndarray) -> Faces:
        """The faces of ``rows`` (M, 15): box, landmarks and score each (YuNet's layout),
        none coarse."""
        rows = np.asarray(rows, np.float64).reshape(-1, 15)
        coarse = np.zeros(len(rows), bool)
        return Faces(rows[:, :4], rows[:, 4:14].reshape(-1, 5, 2), rows[:, 14], coarse)

    def extended(self, more: Faces) -> Faces:
        """These faces followed by ``more``."""
        if len(more) == 0:
            return self
        return Faces(
            np.concatenate([self.boxes, more.boxes]),
            np.concatenate([self.landmarks, more.landmarks]),
            np.concatenate([self.scores, more.scores]),
            np.concatenate([self.coarse, more.coarse]),
        )


@dataclass
class YuNetConfig:
    """``score``: the least score (0..1) a face needs; ``nms``: the overlap (IoU) above which
    two boxes are one face; ``top_k``: faces kept before suppression; ``min_eye_px``: the
    least eye separation, pixels, a face needs (smaller landmarks are too coarse to range);
    ``refine_px``: a face whose eyes are closer than this (pixels) is detected again in a crop
    around it enlarged so its box is ``refine_box_px`` wide (YuNet's landmarks on a small face
    are coarse, about a pixel, i.e. 7 % of the range at 15 pixels between the eyes; 0: never).
    ``candidate``: a small face (eyes closer than ``refine_px``) that the search scores from
    ``candidate`` to ``score`` is looked at again in that crop, where it is larger, and kept
    if the crop is sure of it both ways (:func:`sure_both_ways`; a far face half covered by
    a hand scores 0.2-0.5 in the frame and about 0.9 in the crop); ``candidate`` =
    ``score``: never.
    ``mirror``: each crop is also read mirrored left to right and the two readings averaged
    (:func:`mirror_average`); twice a crop's time, for landmarks that do not lean to one side.
    ``sure``: a face that the search scores from ``score`` to ``sure`` is kept only if its
    refinement crop finds it both as it is and mirrored, scoring ``sure`` on average
    (:meth:`YuNetDetector.confirmed`, :func:`sure_both_ways`): a small one is refined there
    anyway (a live newcomer's first reading is kept unrefined, unless ``refusals``
    remembers a refusal there); a large one (eyes ``refine_px`` apart or more), which the
    crop would only shrink, is looked at for that alone. A face is one both ways; a
    face-like pattern need not be: a cup on a saucer scores 0.64 in the frame and 0.32 in
    its crop, galaxies of the Hubble deep field 0.62-0.75 as far faces and 0.60-0.68 in
    their crops (0.61 mirrored, where found at all). The faces of the tracker's people
    test score 0.90-0.95 when large, and 0.83 or more in their crops either way. A face the
    tracker follows (:meth:`follow`) is kept wherever its crop finds it.
    """

    score: float = 0.6
    nms: float = 0.3
    top_k: int = 50
    min_eye_px: float = 6.0
    refine_px: float = 48.0
    refine_box_px: float = 160.0
    candidate: float = 0.2
    mirror: bool = True
    sure: float = 0.8


class YuNetDetector:
    """YuNet on 8-bit BGR frames of any size. Not thread-safe: one per thread.

    With ``device`` (the tracking camera at the frames' resolution) a face is refined in a
    view pointed at it (:class:`~viewcomp.rt.track.rectify.View`: seen square-on, as in the
    middle of the picture); without, in a plain enlarged crop of the frame (a face far off
    the axis of a wide-angle camera is then seen stretched). With ``refusals`` (one per
    camera, ticked once a frame: :class:`~viewcomp.rt.track.refusals.Refusals`) a place
    where the crop refused an unsure candidate is looked at less and less often; without,
    every time (each frame on its own: files, tests)."""

    def __init__(
        self,
        config: YuNetConfig | None = None,
        path: str | Path = MODEL_PATH,
        device: Device | None = None,
        refusals: Refusals | None = None,
    ) -> None:
        self.config = config or YuNetConfig()
        self.device = device
        self.refusals = refusals
        self.path = check_model(path)
        if not hasattr(cv2, "FaceDetectorYN"):
            raise DetectorError(
                f"OpenCV {cv2.__version__} has no FaceDetectorYN; install "
                "opencv-contrib-python-headless >= 5.0, or use --detector cascade"
            )
        c = self.config
        if not 0.0 < c.candidate <= c.score:
            raise ValueError(f"candidate must be in (0, score={c.score}], got {c.candidate}")
        if not c.score <= c.sure <= 1.0:
            raise ValueError(f"sure must be in [score={c.score}, 1], got {c.sure}")
        try:
            self.net = cv2.FaceDetectorYN.create(
                str(self.path), "", (320, 320), c.candidate, c.nms, c.top_k
            )
        except cv2.error as exc:
            raise DetectorError(f"OpenCV cannot load the face model {self.path}: {exc}") from None
        self._size = (320, 320)
        self.crop_net = cv2.FaceDetectorYN.create(
            str(self.path), "", (320, 320), c.score, c.nms, c.top_k
        )
        self._crop_size = (320, 320)

    def _crop(
        self, frame: np.ndarray, box: np.ndarray, box_px: float | None = None
    ) -> tuple[np.ndarray, Callable[[np.ndarray], np.ndarray]]:
        """The refinement crop of ``box`` (x, y, w, h frame pixels): ``CONTEXT`` box sizes
        each side of its centre, the box ``box_px`` wide (None: ``refine_box_px``), smoothed
        as much as the face's noise calls for (:mod:`viewcomp.rt.track.noise`); and the map
        from the crop's pixels (M, 2) to the frame's."""
        if box_px is None:
            box_px = self.config.refine_box_px
        sigma = smoothing(relative_noise(frame, box))
        if sigma > 0:  # the crop reaches CONTEXT box sizes out; a view off-axis a little more
            frame = smoothed_around(frame, box, sigma, CONTEXT + 0.5)
        if self.device is not None:
            if frame.shape[1::-1] != tuple(self.device.resolution):
                raise ValueError(
                    f"a {frame.shape[1]}x{frame.shape[0]} frame for a tracking camera of "
                    f"{self.device.resolution[0]}x{self.device.resolution[1]} pixels"
                )
            view = View.of_box(self.device, box, box_px, CONTEXT)
            return view.image(frame), view.to_frame
        x0, y0, x1, y1 = around(box, CONTEXT, frame.shape)
        k = box_px / max(box[2], 1.0)
        crop = cv2.resize(frame[y0:y1, x0:x1], None, fx=k, fy=k, interpolation=cv2.INTER_LINEAR)
        # pixel centres at integers in both (as cv2.resize maps them)
        return crop, lambda uv: (np.asarray(uv, np.float64) + 0.5) / k - 0.5 + [x0, y0]

    def refine(
        self, frame: np.ndarray, box: np.ndarray, box_px: float | None = None, both: bool = False
    ) -> np.ndarray | None:
        """(15,) box, landmarks and score of the face in ``box`` (x, y, w, h pixels) found
        again in its refinement crop (:meth:`_crop`: a view pointed at it with a ``device``;
        the box ``box_px`` pixels wide in it, None: ``refine_box_px``), in frame pixels (the
        box: the one around its corners), or None when the crop does not find it or finds
        another face; with ``both``, also unless :func:`sure_both_ways` (read mirrored
        whatever ``mirror`` says)."""
        crop, to_frame = self._crop(frame, box, box_px)
        row = self._read(crop, to_frame, box)
        if row is None:
            return None
        if self.config.mirror or both:
            match = mirror_match(row, self._read_mirrored(crop), crop.shape[1])
            if both and not sure_both_ways(row, match, self.config.sure):
                return None
            if self.config.mirror:
                row = mirror_average(row, match)
        x, y, bw, bh = row[:4]
        corners = to_frame(np.array([[x, y], [x + bw, y], [x, y + bh], [x + bw, y + bh]]))
        lo, hi = corners.min(axis=0), corners.max(axis=0)
        marks = to_frame(row[4:14].reshape(5, 2)).ravel()
        return np.concatenate([lo, hi - lo, marks, row[14:15]])

    def _read(
        self, crop: np.ndarray, to_frame: Callable[[np.ndarray], np.ndarray], box: np.ndarray
    ) -> np.ndarray | None:
        """(15,) the face the crop net finds in ``crop`` (a refinement crop of
        :meth:`_crop`, ``to_frame`` its map to the frame) nearest the centre of ``box`` (x,
        y, w, h frame pixels), in the crop's pixels; None where it finds none within 0.3 of
        the box's width (another face, or none)."""
        size = (crop.shape[1], crop.shape[0])
        if size != self._crop_size:
            self.crop_net.setInputSize(size)
            self._crop_size = size
        _, found = self.crop_net.detect(crop)
        if found is None or len(found) == 0:
            return None
        f = np.asarray(found, np.float64).reshape(-1, 15)
        centre = np.array([box[0] + box[2] / 2, box[1] + box[3] / 2])
        centres = to_frame(f[:, :2] + f[:, 2:4] / 2)
        i = int(np.argmin(np.hypot(*(centres - centre).T)))
        return None if np.hypot(*(centres[i] - centre)) > 0.3 * box[2] else f[i]

    def _read_mirrored(self, crop: np.ndarray) -> np.ndarray:
        """(M, 15) the faces in ``crop`` mirrored (its pixels), after :meth:`_read` of it."""
        _, seen = self.crop_net.detect(cv2.flip(crop, 1))
        return np.zeros((0, 15)) if seen is None else np.asarray(seen, np.float64).reshape(-1, 15)

    def confirmed(self, frame: np.ndarray, box: np.ndarray) -> bool:
        """Whether the face at ``box`` (x, y, w, h pixels) is one its refinement crop is
        sure of both ways (:func:`sure_both_ways`); where ``refusals`` says its crop refused
        one lately, False until it is due again."""
        return self._checked(frame, box, unsure=True) is not None

    def _checked(self, frame: np.ndarray, box: np.ndarray, unsure: bool) -> np.ndarray | None:
        """:meth:`refine` of a face found at ``box`` (x, y, w, h pixels); an ``unsure`` one
        is found both ways or not at all (None), also where ``refusals`` says not yet."""
        seen = self.refusals if unsure else None
        if seen is not None and not seen.due(box):
            return None
        row = self.refine(frame, box, both=unsure)
        if seen is not None:
            seen.refused(box) if row is None else seen.found(box)
        return row

    def _second_look(
        self, frame: np.ndarray, box: np.ndarray, quick: bool
    ) -> tuple[np.ndarray | None, bool]:
        """A small face the search scored under ``score`` at ``box`` (x, y, w, h pixels)
        looked at again: (its row (15,), whether that reading is coarse) where a crop finds
        a face there, else (None, False). With ``quick`` (a newcomer the search saw at
        reduced resolution) first in a crop at the frame's own resolution (a few times
        smaller than the refinement's: a reading as coarse as a full-resolution search's);
        then in the refinement crop, both ways (:func:`sure_both_ways`). Where ``refusals``
        says the refinement crop refused one there lately, not at all."""
        seen = self.refusals
        if seen is not None and not seen.due(box):
            return None, False
        row = self.refine(frame, box, float(box[2])) if quick else None
        coarse = row is not None
        if row is None:
            row = self.refine(frame, box, both=True)
        if seen is not None:
            seen.refused(box) if row is None else seen.found(box)
        return row, coarse

    def follow(self, frame: np.ndarray, boxes: np.ndarray, taken: np.ndarray) -> np.ndarray:
        """(M, 15) box, landmarks and score of the faces of ``boxes`` (K, 4) (where faces were
        seen before) that the frame's search missed, each looked for again in an enlarged
        crop (:meth:`refine`); a box overlapping ``taken`` (the faces found already, (N, 4))
        or another followed face by more than 0.3 IoU is skipped, a face the crop does not
        find is left out. In a crop a far face is several times larger: a hand over the
        mouth of a face 3 m away hides it from the whole-frame search, not from the crop."""
        rows: list[np.ndarray] = []
        taken = np.asarray(taken, np.float64).reshape(-1, 4)
        for box in np.asarray(boxes, np.float64).reshape(-1, 4):
            if overlaps(box, taken):
                continue
            row = self.refine(frame, box)
            if row is None or np.linalg.norm(row[6:8] - row[4:6]) < self.config.min_eye_px:
                continue  # lost (left, hidden): the tracker holds its eye
            rows.append(row)
            taken = np.concatenate([taken, row[None, :4]])
        return np.asarray(rows, np.float64).reshape(-1, 15)

    def detect(
        self,
        frame: np.ndarray,
        scale: float = 1.0,
        follow: np.ndarray | None = None,
        refine_near: np.ndarray | None = None,
    ) -> Faces:
        """The faces in ``frame`` ((h, w, 3) uint8 BGR, or (h, w) uint8 grey), in its pixels.

        ``scale`` < 1 searches the frame resized by that factor (about scale^2 of the time;
        at 0.5 a 1280x720, 90-degree webcam finds faces up to about 2 m, not at 2.5 m); the
        faces found are refined in the full-resolution frame as small faces always are.
        ``follow``: (K, 4) boxes of faces tracked so far; those the search misses are looked
        for around where they were (:meth:`follow`) and come after the faces found.
        ``refine_near`` ((K, 4) boxes): only the small faces overlapping one of them by more
        than 0.3 IoU are refined (None: every small face)."""
        if frame.ndim == 2:
            frame = cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR)
        faces = self._search(frame, scale, refine_near=refine_near)
        if follow is None or len(follow) == 0:
            return faces
        more = self.follow(frame, follow, faces.boxes)
        return faces.extended(Faces.from_rows(more))

    def search_region(
        self,
        frame: np.ndarray,
        region: tuple[int, int, int, int],
        known: np.ndarray,
        refine_near: np.ndarray | None = None,
        scale: float = 1.0,
    ) -> Faces:
        """The faces in ``region`` (x0, y0, width, height pixels) of ``frame`` ((h, w, 3)
        uint8 BGR) at full resolution (``scale`` 1; 2: enlarged twice, so faces half the
        size are found), in the frame's pixels, but those overlapping a box of
        ``known`` ((K, 4): faces found already) by more than 0.3 IoU and those the region's
        edge cuts (:func:`cut`; tiles overlapping by a face's size hold it whole in another
        one, and a part face's landmarks range it wrongly); small faces are refined
        in the whole frame, so a face near the region's edge keeps its context. Regions of
        one size keep the network's input size (changing it costs a set-up). ``refine_near``
        as for :meth:`detect`."""
        return self._search(frame, scale, region, known, refine_near)

    def _search(
        self,
        frame: np.ndarray,
        scale: float,
        region: tuple[int, int, int, int] | None = None,
        known: np.ndarray | None = None,
        refine_near: np.ndarray | None = None,
    ) -> Faces:
        """The search of :meth:`detect` (BGR ``frame``; the whole frame, or ``region``
        without the faces of ``known``, before any is refined; resized by ``scale``, reduced
        with area averaging, enlarged bilinearly); with ``refine_near`` ((K, 4)
        boxes) only the small faces overlapping one of them by more than 0.3 IoU are
        refined; the others keep the search's landmarks (``Faces.coarse``). Faces a region's
        edge cuts (:func:`cut`) are left out: their landmarks are a part face's. A small face
        scored under ``score`` (from ``candidate``) is kept only if a crop finds it, and then
        with the crop's reading (:meth:`_second_look`: coarse only for a newcomer that a
        search at reduced ``scale`` found and a crop at the frame's own resolution confirms);
        a large one is left out, and so is one where ``refusals`` says the refinement crop
        refused one lately. A face scored from ``score`` to ``sure`` is kept only where its
        crop is sure of it both ways (``YuNetConfig.sure``; a newcomer's unrefined first
        reading is kept, unless ``refusals`` remembers a refusal there)."""
        small, x0, y0 = frame, 0, 0
        if region is not None:
            x0, y0, rw, rh = region
            small = frame[y0 : y0 + rh, x0 : x0 + rw]
        if scale != 1.0:
            interp = cv2.INTER_AREA if scale < 1.0 else cv2.INTER_LINEAR
            small = cv2.resize(small, None, fx=scale, fy=scale, interpolation=interp)
        h, w = small.shape[:2]
        if (w, h) != self._size:
            self.net.setInputSize((w, h))
            self._size = (w, h)
        _, found = self.net.detect(small)
        if found is None or len(found) == 0:
            return Faces.empty()
        f = np.asarray(found, np.float64).reshape(-1, 15)
        f = f[np.argsort(-f[:, 14], kind="stable")]
        if scale != 1.0:  # to full-resolution pixels (pixel centres at integers in both)
            xy = [0, 1, *range(4, 14)]
            f[:, xy] = (f[:, xy] + 0.5) / scale - 0.5
            f[:, 2:4] /= scale
        f[:, [0, *range(4, 14, 2)]] += x0  # to the frame's pixels
        f[:, [1, *range(5, 14, 2)]] += y0
        if known is not None and len(known):
            f = f[[not overlaps(row[:4], known) for row in f]].reshape(-1, 15)
        if region is not None:  # a face cut by the region's edge: another region holds it
            f = f[[not cut(row[:4], region, frame.shape) for row in f]].reshape(-1, 15)
        c = self.config
        coarse = np.zeros(len(f), bool)
        keep = np.ones(len(f), bool)
        for i, row in enumerate(f):  # small faces: landmarks again from an enlarged crop
            if np.linalg.norm(row[6:8] - row[4:6]) >= c.refine_px:
                # a large face the crop would only shrink; an unsure one only where it finds it
                keep[i] = row[14] >= c.score and (
                    row[14] >= c.sure or self.confirmed(frame, row[:4].copy())
                )
                continue
            newcomer = refine_near is not None and not overlaps(row[:4], refine_near)
            # where a crop refused one lately, an unsure newcomer is checked, not taken at
            # once: a picture taken for a face would come back each time its track ended
            doubted = newcomer and self.refusals is not None and self.refusals.remembers(row[:4])
            if row[14] < c.score:
                look = newcomer and scale < 1 and not doubted  # the quick look first
                again, quick = self._second_look(frame, row[:4].copy(), look)
                keep[i] = again is not None and not overlaps(again[:4], f[:i][keep[:i], :4])
                if again is not None and keep[i]:
                    row[:], coarse[i] = again, quick
            elif newcomer and not (doubted and row[14] < c.sure):
                coarse[i] = True
            elif (better := self._checked(frame, row[:4].copy(), row[14] < c.sure)) is not None:
                row[:14] = better[:14]
            else:
                keep[i] = row[14] >= c.sure  # an unsure face its crop does not find
        order = np.argsort(-f[keep, 14], kind="stable")  # strongest first again
        f, coarse = f[keep][order], coarse[keep][order]
        marks = f[:, 4:14].reshape(-1, 5, 2)
        sep = np.linalg.norm(marks[:, 1] - marks[:, 0], axis=1)
        keep = sep >= c.min_eye_px
        return Faces(f[keep, :4], marks[keep], f[keep, 14], coarse[keep])
