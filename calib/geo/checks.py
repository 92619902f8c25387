"""Checks of a camera-space set: the camera did not move, the patterns are in order, the
Gray code covers the projector image.

The camera-moved check of `calibrate` (:class:`MoveCheck`): an old capture set has no gray
shown again between its captures (`capture` checks that live), so each capture's projector
frame is compared with screen/graycode_white's, and each Gray-code plane summed with its
inverse (the whole frame lit), by :func:`~viewcomp.calib.geo.framematch.frame_shift`, the
comparison `capture` uses: highlights and clipped pixels are left out, so a glossy screen's
highlight, whose shape changes with every pattern, does not pass for a moved frame.

Each refusal is a :class:`~viewcomp.calib.errors.FitError` naming the capture and the fix.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np

from viewcomp.calib.errors import FitError
from viewcomp.calib.geo.captures import Captures, channel_mean
from viewcomp.calib.geo.framematch import (
    MIN_MATCH,
    MOVE_LIMIT_PX,
    FrameEdges,
    frame_edges,
    frame_shift,
    lit_region,
)
from viewcomp.calib.geo.graycode import GrayCode, lit_mask
from viewcomp.calib.io.checks import MASK_LIMIT, SATURATION_LIMIT
from viewcomp.calib.io.patterns import PRIMARY_PATTERNS

REFERENCE = "gray"  # the reference of a set other than the real screen's
TABLE1 = ("black", "gray", "red", "green", "blue", "ramp")  # refused by check_captures when clipped
COVERAGE_CELLS = (16, 8)  # every cell of this grid over the projector image must decode


def check_pattern_order(images: Mapping[str, np.ndarray], sub: str) -> None:
    """Refuse Table-1 captures that are not what their names say (wrong order, mislabelled).

    ``images``: name -> (H, W, 3) linear on the projector grid. Checks that gray is brighter
    than black, red/green/blue raise their own camera channel most over gray, and the ramp
    rises from left to right (the ramp over gray, per pixel, so that a glossy screen's
    highlight, as bright in both, does not bend it).

    Raises:
        FitError: naming the capture and the fix.
    """
    fix = (
        "the captures are in the wrong order or mislabelled: capture red (130,110,110, or "
        "255 in red as `viewcomp capture` shows it), green, blue, gray (110,110,110) and the "
        "ramp as `viewcomp patterns` writes them"
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
    ramp = _ramp_profile(images, inner[0])
    cols = np.arange(ramp.size, dtype=np.float64)
    corr = float(np.corrcoef(cols, ramp)[0, 1]) if ramp.std() > 0 else 0.0
    if not corr > 0.9:
        raise FitError(
            f"{sub}/ramp",
            f"does not rise from left to right (correlation with the column {corr:+.2f}): {fix}",
        )


def _ramp_profile(images: Mapping[str, np.ndarray], rows: slice) -> np.ndarray:
    """(W,) the ramp's rise per column: the median over ``rows`` of (ramp - black) / (gray -
    black) (black 0 when missing; gray floored at a tenth of its median), the screen's
    reflectance and highlights divided out."""
    black = np.asarray(images.get("black", 0.0), np.float64)
    ramp = (np.asarray(images["ramp"], np.float64) - black)[rows].sum(axis=2)
    gray = (np.asarray(images["gray"], np.float64) - black)[rows].sum(axis=2)
    floor = max(0.1 * float(np.median(gray)), 1e-9)
    return np.median(ramp / np.maximum(gray, floor), axis=0)


class MoveCheck:
    """Captures that show the projector's frame (Table 1 but black, the chessboards, each
    Gray-code plane plus its inverse) against their set's reference (see the module doc):
    the real screen's against screen/graycode_white, the white screen's against white/gray
    (a screen's texture or highlight is not in the other's captures; the two sets are tied
    by their chessboards' corners, or, without a white chessboard, by white/gray against
    screen/graycode_white). The frame must be matched and within :data:`MOVE_LIMIT_PX`.
    ``worst`` keeps the largest shift (camera px)."""

    def __init__(self, screen: Captures, tied: bool = True) -> None:
        """``tied``: the white set is tied to the real screen's by the chessboards."""
        self.screen = screen
        self.tied = tied
        ref = screen.get("graycode_white")
        self.black = screen.get("graycode_black")
        self.lit, _ = lit_mask(
            channel_mean(ref), channel_mean(self.black), screen.rel("graycode_white")
        )
        self.lit_level = float((ref - self.black)[self.lit].mean())
        self.region = lit_region(ref, self.black)
        edges = frame_edges(ref, self.region, _clipped(screen, "graycode_white", ref))
        self.refs: dict[str, tuple[str, FrameEdges]] = {
            screen.sub: (screen.rel("graycode_white"), edges)
        }
        self.worst = 0.0
        self.pending: FitError | None = None

    def _reference(self, caps: Captures, name: str) -> tuple[str, FrameEdges] | None:
        """The reference of ``caps``'s set (its gray, for a set other than the real
        screen's); None for that gray itself when the chessboards tie the sets."""
        if caps.sub not in self.refs:
            gray = caps.get(REFERENCE)
            self.refs[caps.sub] = (
                caps.rel(REFERENCE),
                frame_edges(gray, self.region, _clipped(caps, REFERENCE, gray)),
            )
        if caps.sub != self.screen.sub and name == REFERENCE:
            return None if self.tied else self.refs[self.screen.sub]
        return self.refs[caps.sub]

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
        """Check one capture (Hc, Wc, 3) linear (or a Gray-code plane + its inverse, named by
        the plane); ``in_view`` raises first when the frame is not wholly seen (a clearer
        reason for a failed match); without it a failed match is held back for
        :meth:`flush`.

        Raises:
            FitError: a capture as dark as black (wrong order, projector off; not a primary
                shown alone, which a screen of another colour may leave dark), or whose frame
                has moved (the camera moved between captures) or cannot be matched.
        """
        level = float((img - self.black)[self.lit].mean()) / max(self.lit_level, 1e-9)
        # a primary shown alone may be as dark as black on a screen that barely reflects it
        if level < 0.02 and name not in PRIMARY_PATTERNS:
            raise FitError(
                caps.rel(name),
                f"does not show the projected pattern (where the projector lights, it is "
                f"{level:.1%} as bright as graycode_white, as dark as black): the captures are "
                "in the wrong order or mislabelled, or the projector was off; capture again",
            )
        reference = self._reference(caps, name)
        clipped = _clipped(caps, name, img)
        share = 0.0 if clipped is None else float(clipped[self.region].mean())
        limit = MASK_LIMIT if caps.sub == self.screen.sub else SATURATION_LIMIT
        if reference is None or (name in TABLE1 and share > limit):
            return  # a capture clipped this much hides its frame; check_captures names it
        ref_rel, ref_edges = reference
        shift = frame_shift(ref_edges, frame_edges(img, self.region, clipped))
        if shift.match < MIN_MATCH:
            error = FitError(
                caps.rel(name),
                f"the projector's frame cannot be matched with {ref_rel}'s (correlation "
                f"{shift.match:.2f}): the camera moved a lot, the frame is not wholly in view, "
                "or this is not a capture of this rig; fix the camera so that it sees the whole "
                "projected image and capture the set again",
            )
            if in_view is None:  # decide once it is known whether the frame is in view
                self.pending = self.pending or error
                return
            in_view()
            raise error
        d = shift.distance
        if d > MOVE_LIMIT_PX:
            raise FitError(
                caps.rel(name),
                f"the projector's frame lies {d:.1f} camera px from where {ref_rel} has it: the "
                "camera moved between captures; fix the camera (and lock its zoom and focus) "
                "and capture the set again",
            )
        self.worst = max(self.worst, d)


def _clipped(caps: Captures, name: str, img: np.ndarray) -> np.ndarray | None:
    """(Hc, Wc) bool: the pixels of a capture read from codes that reached the top code
    (which decodes to 1.0; a sum of a plane and its inverse is 1.0 or more there); None for
    a capture whose codes never reached it, or a float (HDR) capture, whose light above 1.0
    is not clipped."""
    if caps.saturation.get(name, 0.0) <= 0:
        return None
    return np.any(np.asarray(img) >= 1.0, axis=-1)


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
