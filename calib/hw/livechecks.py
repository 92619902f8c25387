"""The checks `viewcomp capture` runs on each capture as it arrives, so that a problem is
named while the user can still fix it: saturated, too dark or not visible, wrong colour
pattern, camera moved, chessboard not found (the list is in :mod:`viewcomp.calib.hw.procedure`).

Camera moved: each stage's first gray is its reference; gray is shown again every few
captures (:mod:`viewcomp.calib.hw.plan`). Every capture's projector frame is compared
(:func:`~viewcomp.calib.geo.framematch.frame_shift`: highlights and clipped pixels left out)
with the latest showing of gray, so a capture is compared with a reference taken moments
before rather than with captures of other patterns; a Gray-code plane is compared summed with
its inverse (the whole frame lit). Each showing of gray is compared, like with like, with the
stage's first: a slow drift adds up there. The chessboard of the real screen is compared with
the white screen's by its corners.
"""

from __future__ import annotations

import numpy as np

from viewcomp.calib.geo.chessboard import find_corners
from viewcomp.calib.geo.framematch import (
    MIN_MATCH,
    MOVE_LIMIT_PX,
    FrameEdges,
    Shift,
    frame_edges,
    frame_shift,
    lit_region,
)
from viewcomp.calib.hw.plan import REFERENCE, is_reference_again
from viewcomp.calib.io.checks import DARK_LIMIT, SATURATION_LIMIT
from viewcomp.calib.io.imageio import CaptureError, to_linear
from viewcomp.calib.world.response import Response

VISIBLE_LIMIT = 0.01  # linear: gray - black must exceed this to count as lit
MIN_LIT_FRACTION = 0.005  # of the camera image


class LiveChecks:
    """The checks run on each capture as it arrives (see the module doc).

    ``response`` linearises the camera's codes; ``projector_size`` (W, H) places the
    chessboard's corners.
    """

    def __init__(self, response: Response, projector_size: tuple[int, int]) -> None:
        self.response = response
        self.projector_size = projector_size
        self.black: dict[str, np.ndarray] = {}
        self.gray: dict[str, np.ndarray] = {}
        self.lit: dict[str, np.ndarray] = {}
        self.corners: dict[str, np.ndarray] = {}
        self.pending: dict[str, tuple[str, np.ndarray, np.ndarray | None]] = {}
        #: per stage: the lit region of its first gray, that gray's edges, and the latest
        #: showing of gray (its name and edges)
        self.region: dict[str, np.ndarray] = {}
        self.first: dict[str, FrameEdges] = {}
        self.latest: dict[str, tuple[str, FrameEdges]] = {}
        #: per stage: the last capture whose frame matched (where the camera was still in place)
        self.still: dict[str, str] = {}
        #: the largest frame shift seen (camera px) and the capture that showed it
        self.worst: tuple[float, str] = (0.0, "")

    def linear(self, raw: np.ndarray) -> np.ndarray:
        """(H, W, 3) codes -> float32 linear 0..1."""
        return to_linear(raw, self.response)

    def _clipped_fraction(self, sub: str, at_top: np.ndarray) -> float:
        """Fraction of the lit pixels (all before ``sub``'s gray) with a channel at the top:
        ``at_top`` (H, W, 3) bool."""
        mask = self.lit.get(sub)
        hit = np.any(at_top, axis=2) if mask is None else at_top[mask]
        return float(np.count_nonzero(hit)) / max(hit.size, 1)

    def check(self, sub: str, name: str, raw: np.ndarray) -> None:
        """Check one capture; raises CaptureError naming it and the fix."""
        rel = f"{sub}/{name}"
        if raw.ndim != 3 or raw.shape[2] != 3 or raw.dtype not in (np.uint8, np.uint16):
            raise CaptureError(f"{rel}: the camera returned {raw.shape} {raw.dtype}, not RGB")
        top = 255 if raw.dtype == np.uint8 else 65535
        at_top = raw >= top
        frac = self._clipped_fraction(sub, at_top)
        if frac > SATURATION_LIMIT:
            raise CaptureError(
                f"{rel}: {frac:.1%} of the lit pixels are at the maximum code (saturated): "
                "lower the camera's exposure (--exposure) or the projector's brightness, or "
                "capture with --hdr, and capture again"
            )
        self.check_linear(sub, name, self.linear(raw), np.any(at_top, axis=2))

    def check_merged(self, sub: str, name: str, lin: np.ndarray, clipped: np.ndarray) -> None:
        """Check one HDR capture: ``lin`` (H, W, 3) float32 merged linear light, ``clipped``
        (H, W, 3) bool the pixel-channels clipped in every frame of the bracket."""
        rel = f"{sub}/{name}"
        frac = self._clipped_fraction(sub, clipped)
        if frac > SATURATION_LIMIT:
            raise CaptureError(
                f"{rel}: {frac:.1%} of the lit pixels are clipped even in the bracket's shortest "
                "exposure: lower the camera's exposure (--exposure), or, when that is one "
                "projector refresh period already (an upward bracket), the projector's "
                "brightness (or add an ND filter), and capture again"
            )
        self.check_linear(sub, name, lin, np.any(clipped, axis=2))

    def check_linear(
        self, sub: str, name: str, lin: np.ndarray, clipped: np.ndarray | None = None
    ) -> None:
        """The checks of :meth:`check` after saturation, on the linear capture (H, W, 3);
        ``clipped`` (H, W) bool: pixels at the top code (left out of the frame's match)."""
        rel = f"{sub}/{name}"
        if name == "black":
            self.black[sub] = lin
            return
        if name == REFERENCE:
            self._first_gray(sub, rel, lin, clipped)
            return
        if is_reference_again(name):
            self.moved(sub, rel, lin, clipped)
            return
        if sub not in self.gray:
            raise CaptureError(f"{rel}: captured before {sub}/gray; use capture_plan's order")
        if name in ("red", "green", "blue"):
            self._colour(sub, rel, name, lin)
        if name == "chessboard":
            self._chessboard(sub, rel, lin)
        still = rel
        if name.startswith("graycode_") and name[9:].isdigit():
            if int(name[9:]) % 2 == 0:
                self.pending[sub] = (rel, lin, clipped)
                return
            if sub in self.pending:  # a plane + its inverse: the whole frame lit
                still, plane, plane_clipped = self.pending.pop(sub)
                lin = lin + plane
                clipped = _either(clipped, plane_clipped)
                rel = f"{still} + {name}"
        if name != "graycode_black":
            self._against_latest(sub, rel, lin, clipped, still)

    def _first_gray(self, sub: str, rel: str, lin: np.ndarray, clipped: np.ndarray | None) -> None:
        black = self.black.get(sub, np.zeros_like(lin))
        diff = (lin - black).mean(axis=2)
        peak = float(np.percentile(diff, 99.5))
        lit = diff > max(VISIBLE_LIMIT, 0.3 * peak)
        if peak < VISIBLE_LIMIT or lit.mean() < MIN_LIT_FRACTION:
            raise CaptureError(
                f"{rel}: the projected image is not visible to the camera (gray is at most "
                f"{peak:.3f} above black, lit area {lit.mean():.2%} of the frame): check that "
                "the window is on the projector (--monitor, see --list-monitors), that the "
                "camera sees the screen, and the exposure"
            )
        level = float(lin[lit].mean())
        if level < DARK_LIMIT:
            raise CaptureError(
                f"{rel}: too dark (mean linear level {level:.4f} where the projector lights): "
                "raise the camera's exposure or darken the room, and capture again"
            )
        self.gray[sub] = lin
        self.lit[sub] = lit
        self.region[sub] = lit_region(lin, self.black.get(sub))
        edges = frame_edges(lin, self.region[sub], clipped)
        self.first[sub] = edges
        self.latest[sub] = (rel, edges)
        self.still[sub] = rel

    def _colour(self, sub: str, rel: str, name: str, lin: np.ndarray) -> None:
        c = ("red", "green", "blue").index(name)
        d = (lin - self.gray[sub])[self.lit[sub]].mean(axis=0)
        if d[c] <= 0 or d[c] <= max(d[(c + 1) % 3], d[(c + 2) % 3]):
            raise CaptureError(
                f"{rel}: the {name} pattern does not raise the camera's {name} channel most "
                f"(change over gray R,G,B = {d[0]:+.4f}, {d[1]:+.4f}, {d[2]:+.4f}): check the "
                "projector's colour mode and that the window is on the projector"
            )

    def _chessboard(self, sub: str, rel: str, lin: np.ndarray) -> None:
        shading = self.gray[sub], self.black.get(sub)
        corners = find_corners(lin, self.projector_size, rel, *shading).camera
        self.corners[sub] = corners
        if sub == "screen" and "white" in self.corners:
            shift = float(np.sqrt(np.mean(np.sum((corners - self.corners["white"]) ** 2, 1))))
            if shift > MOVE_LIMIT_PX:
                raise CaptureError(
                    f"{rel}: the chessboard lies {shift:.1f} camera px from where it was on the "
                    "white screen: the camera moved, or the real screen is not where the white "
                    "one was; put it in the same place, fix the camera, and capture again"
                )

    def _shift(self, sub: str, rel: str, edges: FrameEdges, against: FrameEdges) -> Shift:
        """The frame's shift from ``against``; refuses a capture that does not match it."""
        shift = frame_shift(against, edges)
        if shift.match < MIN_MATCH:
            raise CaptureError(
                f"{rel}: the projector's frame is not where {sub}/gray has it (no clear match, "
                f"correlation {shift.match:.2f}; {self.still[sub]} still matched): the camera "
                "moved a lot, or the projector stopped showing; fix the camera and capture again"
            )
        if shift.distance > self.worst[0]:
            self.worst = (shift.distance, rel)
        return shift

    def _against_latest(
        self, sub: str, rel: str, lin: np.ndarray, clipped: np.ndarray | None, still: str
    ) -> None:
        """Refuse a capture whose frame lies more than MOVE_LIMIT_PX from the latest gray's;
        once it matches, the camera is known to have been in place at ``still`` (``rel``, or
        for a plane + its inverse the plane: a move between the two, half in the sum, may
        pass here and is caught at the next capture)."""
        ref_rel, ref = self.latest[sub]
        d = self._shift(sub, rel, frame_edges(lin, self.region[sub], clipped), ref).distance
        if d > MOVE_LIMIT_PX:
            raise CaptureError(
                f"{rel}: the projector's frame lies {d:.1f} camera px from where {ref_rel} has "
                f"it: the camera moved (or was bumped) after {self.still[sub]}; fix it, lock "
                "zoom and focus, and capture again"
            )
        self.still[sub] = still

    def moved(self, sub: str, rel: str, lin: np.ndarray, clipped: np.ndarray | None = None) -> None:
        """Check gray shown again (``lin`` (H, W, 3) linear, ``clipped`` (H, W) bool or None)
        against the stage's first gray and its latest showing, like with like; it becomes
        the latest. Refuses it when the frame lies more than MOVE_LIMIT_PX from either."""
        edges = frame_edges(lin, self.region[sub], clipped)
        first = f"{sub}/{REFERENCE}"
        last_rel, last = self.latest[sub]
        total = self._shift(sub, rel, edges, self.first[sub]).distance
        step = total if last is self.first[sub] else self._shift(sub, rel, edges, last).distance
        if max(total, step) > MOVE_LIMIT_PX:
            raise CaptureError(
                f"{rel}: the projector's frame lies {total:.1f} camera px from where {first} "
                f"had it ({step:.1f} px from {last_rel}): the camera moved (or was bumped, or "
                f"drifted) after {self.still[sub]}; fix it, lock zoom and focus, and capture "
                "again"
            )
        self.latest[sub] = (rel, edges)
        self.still[sub] = rel


def _either(a: np.ndarray | None, b: np.ndarray | None) -> np.ndarray | None:
    """The union of two optional masks."""
    if a is None or b is None:
        return a if b is None else b
    return a | b
