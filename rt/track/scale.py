"""A viewer's face size from its own appearance: template matching against a near view.

The cascade's box is a coarse measure of size: on the simulated walk its width is off by up
to ~9 % at 40-50 pixels, depending on how the face falls on the cascade's grid, and the
distance (Z = f W / w) inherits that error, which at 40 degrees aside moves the eye mostly
in x. A face seen near (a box of at least ``anchor_px`` pixels, where the cascade is within
about 2 %) is kept as a template; in later frames the face is found by normalised
cross-correlation with the template resized to a range of widths around the cascade's, and
the best width and place replace the cascade's box. The template is taken again whenever
the face is seen larger than it was, and dropped when the correlation falls below
``min_score`` (the head turned), until it can be taken again.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np


@dataclass
class ScaleConfig:
    """``anchor_px``: the least box width (pixels) a template is taken from; ``span``: the
    widths tried, a factor either way of the cascade's; ``match_px``: a larger face is
    matched on images scaled down to this width (cost; the sub-pixel peak keeps about 1 %);
    ``min_score``: the correlation (0..1) below which the cascade's box is kept."""

    anchor_px: float = 64.0
    span: float = 1.15
    match_px: float = 48.0
    min_score: float = 0.6


class FaceTemplate:
    """One viewer's face as seen near: a grey patch (h, w) float32 and the box it came from."""

    def __init__(self, gray: np.ndarray, box: np.ndarray) -> None:
        x, y, w, h = (int(np.rint(v)) for v in box)
        self.patch = gray[y : y + h, x : x + w].astype(np.float32)
        self.width = float(self.patch.shape[1])

    @staticmethod
    def fits(gray: np.ndarray, box: np.ndarray) -> bool:
        """True if ``box`` lies inside the frame (a template needs the whole face)."""
        x, y, w, h = box
        return x >= 0 and y >= 0 and x + w <= gray.shape[1] and y + h <= gray.shape[0]

    def measure(
        self, gray: np.ndarray, box: np.ndarray, config: ScaleConfig
    ) -> tuple[np.ndarray, float] | None:
        """The face near ``box`` (x, y, w, h) as the template finds it: (box, score), or None
        when the best correlation is below ``config.min_score``.

        Every whole width from w / span to w span is tried; the width is then refined
        between whole pixels by a parabola through the best score and its neighbours."""
        x, y, w, _ = (float(v) for v in box)
        m = 0.25 * w * config.span
        x0, y0 = max(0, int(x - m)), max(0, int(y - m))
        x1 = min(gray.shape[1], int(np.ceil(x + w * config.span + m)))
        y1 = min(gray.shape[0], int(np.ceil(y + w * config.span + m)))
        roi: np.ndarray = gray[y0:y1, x0:x1].astype(np.float32)
        if min(roi.shape[:2]) < 8:  # the box lies (almost) outside the frame
            return None
        q = min(1.0, config.match_px / w)  # match on a scaled-down copy of a large face
        if q < 1.0:
            roi = cv2.resize(roi, None, fx=q, fy=q, interpolation=cv2.INTER_AREA)
        wq = w * q
        widths = range(max(8, int(wq / config.span)), int(np.ceil(wq * config.span)) + 1)
        scores, places = [], []
        for tw in widths:
            th = max(8, int(np.rint(self.patch.shape[0] * tw / self.width)))
            if tw >= roi.shape[1] or th >= roi.shape[0]:
                break
            inter = cv2.INTER_AREA if tw < self.width else cv2.INTER_LINEAR
            t = cv2.resize(self.patch, (tw, th), interpolation=inter)
            _, score, _, loc = cv2.minMaxLoc(cv2.matchTemplate(roi, t, cv2.TM_CCOEFF_NORMED))
            scores.append(float(score))
            places.append(loc)
        if not scores:
            return None
        k = int(np.argmax(scores))
        if scores[k] < config.min_score:
            return None
        shift = 0.0
        if 0 < k < len(scores) - 1:
            a, b, c = scores[k - 1], scores[k], scores[k + 1]
            den = a - 2 * b + c
            shift = 0.5 * (a - c) / den if den < 0 else 0.0
        bw = (widths[k] + shift) / q
        bx = x0 + (places[k][0] - shift / 2) / q
        by = y0 + (places[k][1] - shift / 2) / q
        return np.array([bx, by, bw, bw]), scores[k]
