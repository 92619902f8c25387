"""Checks of a camera-space set: the camera did not move, the patterns are in order, the
Gray code covers the projector image.

Each refusal is a :class:`~viewcomp.calib.errors.FitError` naming the capture and the fix.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import cv2
import numpy as np

from viewcomp.calib.errors import FitError
from viewcomp.calib.geo.captures import Captures, channel_mean
from viewcomp.calib.geo.graycode import GrayCode, lit_mask

MOVE_LIMIT_PX = 1.0  # camera pixels: a larger shift between captures means the camera moved
MIN_PEAK = 0.1  # phase-correlation peak below which two captures do not show the same frame
COVERAGE_CELLS = (16, 8)  # every cell of this grid over the projector image must decode


def edge_image(img: np.ndarray) -> np.ndarray:
    """(Hc, Wc) float32 sharp edges of a linear image (Hc, Wc, 3): the gradient magnitude minus
    its local mean (a ramp's steady slope and smooth shading vanish, the projector frame's and
    the chessboard's edges stay)."""
    g = channel_mean(img)
    top = float(np.percentile(g, 99.5))
    g = g / max(top, 1e-6)
    gx = cv2.Sobel(g, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(g, cv2.CV_32F, 0, 1, ksize=3)
    e = np.sqrt(gx * gx + gy * gy)
    return np.maximum(e - cv2.GaussianBlur(e, (0, 0), 4.0), 0.0)


def frame_shift(reference: np.ndarray, image: np.ndarray) -> tuple[float, float]:
    """How far (camera px) ``image``'s sharp edges (the projector frame's) have moved from
    ``reference``'s, by phase correlation; both (Hc, Wc, 3) linear, or ``reference`` already
    an edge image (Hc, Wc) of :func:`edge_image`. Returns (shift, peak): ``peak`` in 0..1 says
    how clearly the images match (a capture of a lit pattern against another: > 0.3; below
    :data:`MIN_PEAK` the shift means nothing)."""
    ref = reference if reference.ndim == 2 else edge_image(reference)
    (dx, dy), peak = cv2.phaseCorrelate(ref, edge_image(image))
    return float(np.hypot(dx, dy)), float(peak)


def check_pattern_order(images: Mapping[str, np.ndarray], sub: str) -> None:
    """Refuse Table-1 captures that are not what their names say (wrong order, mislabelled).

    ``images``: name -> (H, W, 3) linear on the projector grid. Checks that gray is brighter
    than black, red/green/blue raise their own camera channel most over gray, and the ramp
    rises from left to right.

    Raises:
        FitError: naming the capture and the fix.
    """
    fix = (
        "the captures are in the wrong order or mislabelled: capture red (130,110,110), green "
        "(110,130,110), blue (110,110,130), gray (110,110,110) and the ramp as `viewcomp "
        "patterns` writes them"
    )
    h, w = images["gray"].shape[:2]
    inner = (slice(h // 10, h - h // 10), slice(w // 10, w - w // 10))
    mean = {
        k: np.asarray(v, np.float64)[inner].reshape(-1, 3).mean(axis=0) for k, v in images.items()
    }
    if "black" in mean and mean["gray"].sum() <= mean["black"].sum():
        raise FitError(f"{sub}/gray", f"is not brighter than {sub}/black: {fix}")
    for c, name in enumerate(("red", "green", "blue")):
        d = mean[name] - mean["gray"]
        if d[c] <= 0 or d[c] <= max(d[(c + 1) % 3], d[(c + 2) % 3]):
            raise FitError(
                f"{sub}/{name}",
                f"does not raise the {name} camera channel most over {sub}/gray (change "
                f"R,G,B = {d[0]:+.4f}, {d[1]:+.4f}, {d[2]:+.4f}): {fix}",
            )
    ramp = np.asarray(images["ramp"], np.float64)[inner[0]].mean(axis=(0, 2))
    cols = np.arange(ramp.size, dtype=np.float64)
    corr = float(np.corrcoef(cols, ramp)[0, 1]) if ramp.std() > 0 else 0.0
    if not corr > 0.9:
        raise FitError(
            f"{sub}/ramp",
            f"does not rise from left to right (correlation with the column {corr:+.2f}): {fix}",
        )


class MoveCheck:
    """Captures that show the projector's frame (Table 1 but black, the chessboards, each
    Gray-code plane plus its inverse) against screen/graycode_white: the frame must be visible
    and within :data:`MOVE_LIMIT_PX`. ``worst`` keeps the largest shift (camera px)."""

    def __init__(self, screen: Captures) -> None:
        self.screen = screen
        ref = screen.get("graycode_white")
        self.black = screen.get("graycode_black")
        self.lit, _ = lit_mask(
            channel_mean(ref), channel_mean(self.black), screen.rel("graycode_white")
        )
        self.lit_level = float((ref - self.black)[self.lit].mean())
        self.ref_edges = edge_image(ref)
        self.worst = 0.0
        self.pending: FitError | None = None

    def flush(self, in_view: Callable[[], None]) -> None:
        """Raise a failed match held back (``in_view`` first: the clearer reason)."""
        if self.pending is not None:
            in_view()
            raise self.pending

    def __call__(
        self,
        caps: Captures,
        name: str,
        img: np.ndarray,
        in_view: Callable[[], None] | None = None,
    ) -> None:
        """Check one capture (Hc, Wc, 3) linear; ``in_view`` raises first when the frame is
        not wholly seen (a clearer reason for a failed match); without it a failed match is
        held back for :meth:`flush`.

        Raises:
            FitError: a capture as dark as black (wrong order, projector off), or whose frame
                has moved (the camera moved between captures) or cannot be matched.
        """
        ref_rel = self.screen.rel("graycode_white")
        level = float((img - self.black)[self.lit].mean()) / max(self.lit_level, 1e-9)
        if level < 0.02:
            raise FitError(
                caps.rel(name),
                f"does not show the projected pattern (where the projector lights, it is "
                f"{level:.1%} as bright as graycode_white, as dark as black): the captures are "
                "in the wrong order or mislabelled, or the projector was off; capture again",
            )
        d, peak = frame_shift(self.ref_edges, img)
        if peak < MIN_PEAK:
            error = FitError(
                caps.rel(name),
                f"the projector's frame cannot be matched with {ref_rel}'s (phase-correlation "
                f"peak {peak:.2f}): the camera moved a lot, the frame is not wholly in view, or "
                "this is not a capture of this rig; fix the camera so that it sees the whole "
                "projected image and capture the set again",
            )
            if in_view is None:  # decide once it is known whether the frame is in view
                self.pending = self.pending or error
                return
            in_view()
            raise error
        if d > MOVE_LIMIT_PX:
            raise FitError(
                caps.rel(name),
                f"the projector's frame lies {d:.1f} camera px from where {ref_rel} has it: the "
                "camera moved between captures; fix the camera (and lock its zoom and focus) "
                "and capture the set again",
            )
        self.worst = max(self.worst, d)


def check_coverage(gc: GrayCode, size: tuple[int, int], rel: str) -> None:
    """Refuse a Gray code that leaves a part of the projector image undecoded (the map would
    extrapolate there): every cell of a COVERAGE_CELLS grid over the projector image must hold
    decoded camera pixels."""
    w, h = size
    cols, rows = COVERAGE_CELLS
    ok = gc.column >= 0
    cu = np.minimum(gc.column[ok] * cols // w, cols - 1)
    cv = np.minimum(gc.row[ok] * rows // h, rows - 1)
    counts = np.bincount(cv * cols + cu, minlength=cols * rows).reshape(rows, cols)
    empty = np.argwhere(counts == 0)
    if len(empty):
        r, c = empty[0]
        u, v = int((c + 0.5) * w / cols), int((r + 0.5) * h / rows)
        raise FitError(
            rel,
            f"the Gray code is not decoded in {len(empty)} of {cols * rows} parts of the "
            f"projector image (e.g. around projector pixel ({u}, {v})): the camera does not see "
            "that part (out of view, occluded) or the screen is too dark there; make the whole "
            "projected image visible to the camera and capture again",
        )
