"""Face boxes (x, y, w, h pixels, top-left corner): how much two of them overlap, and the
square of a frame around one."""

from __future__ import annotations

import numpy as np


def iou(box: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """Intersection over union (0..1) of ``box`` (4,) with each of ``boxes`` (N, 4), x y w h
    (0 where both are empty)."""
    b = np.asarray(boxes, np.float64).reshape(-1, 4)
    ix = np.clip(
        np.minimum(box[0] + box[2], b[:, 0] + b[:, 2]) - np.maximum(box[0], b[:, 0]), 0, None
    )
    iy = np.clip(
        np.minimum(box[1] + box[3], b[:, 1] + b[:, 3]) - np.maximum(box[1], b[:, 1]), 0, None
    )
    inter = ix * iy
    union = box[2] * box[3] + b[:, 2] * b[:, 3] - inter
    return np.divide(inter, union, out=np.zeros_like(inter), where=union > 0)  # empty: 0


SAME_FACE = 0.3  # the IoU above which two boxes are taken for one face


def overlaps(box: np.ndarray, boxes: np.ndarray) -> bool:
    """Whether ``box`` (4,) and any of ``boxes`` (N, 4), x y w h, are one face (IoU above
    :data:`SAME_FACE`); False for no boxes."""
    return len(boxes) > 0 and float(np.max(iou(box, boxes))) > SAME_FACE


def around(box: np.ndarray, sides: float, shape: tuple[int, ...]) -> tuple[int, int, int, int]:
    """(x0, y0, x1, y1) pixels: the square ``sides`` box sizes (the larger of width and
    height) each side of ``box``'s centre, cut to a frame of ``shape`` ((h, w, ...))."""
    x, y, w, h = (float(v) for v in box[:4])
    side = sides * max(w, h)
    cx, cy = x + w / 2.0, y + h / 2.0
    fh, fw = shape[:2]
    return (
        int(max(0, cx - side)), int(max(0, cy - side)),
        int(min(fw, cx + side)), int(min(fh, cy + side)),
    )  # fmt: skip
