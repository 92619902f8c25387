"""Projector-dimmed HDR stops: light that even the bracket's shortest exposure clips.

An HDR bracket's exposures are whole projector refresh periods
(:mod:`~viewcomp.calib.hw.bracket`), so its shortest stop holds at least one period of light;
a glossy screen's highlight can be brighter than that at gain 1. Instead of a shorter
exposure, the projector sends less light: the pattern is shown again with its drive levels
scaled by :data:`DRIVE_STEP` (then its square), and the camera takes it at the shortest stop.

The projector's response is not linear (and not known to the capture), so the light ratio
between a pattern and its dimmed copy is measured, not derived from the drive scale. It can
be measured in the capture itself because the dimming only applies to patterns whose pixels
show at most one level other than black (:func:`single_level`: the uniform colours, white,
the chessboard and every Gray-code plane): all their lit pixels show one drive triple t, so
in camera channel k the light above black of the dimmed copy is r_k times the pattern's
everywhere (pixels that mix lit and black projector pixels included):

    L'_k(x) - B_k(x) = r_k (L_k(x) - B_k(x)),   r_k = response_k(D(t)) / response_k(t)

with B the stage's black capture (room light and the projector's leak, not dimmed).
:func:`measured_ratio` finds r_k where neither capture clips and the dimmed frame holds
projector light well above the black capture's (ratio of sums: the bright pixels weigh
most); :func:`fill_clipped` then gives the clipped pixel-channels B + (L' - B) / r. Pixels
that are bright only because of the room's light are left out: their light above black is
noise, and a Gray-code plane whose lit stripes all clip has thousands of them (measured: an
emulated mono webcam on satin_gold read r = 0.94 there instead of 0.24). r_k is per camera
channel: it holds whatever the projector's primaries, its white segment and their mixing in
the camera do, as long as the screen's reflectance scales each camera channel alone (a
diagonal reflectance, as the simulator's). For a triple of unequal levels (the colour
patterns) each primary dims by its own ratio, so r_k is exact only where a camera channel
sees one primary; dimming with drives that give every primary the emulator's true ratio
changed no measured figure (the webcam's HDR rows on satin_gold, the most clipped).

A pattern of many levels (the ramp, the phase-shifted fringes) is dimmed too, by the mean
ratio of its own unclipped pixels: each level dims by its own ratio (the response is not a
power law) and the capture does not know a camera pixel's level yet (no camera -> projector map
before the Gray code), so what it recovers there is approximate (docs/INTERFACES.md, HDR).
"""

from __future__ import annotations

from collections.abc import Callable

import cv2
import numpy as np

from viewcomp.calib.io.hdr import CLIP_CODE, merge_exposures
from viewcomp.calib.world.response import Response

Log = Callable[[str], None]

#: Drive scale of each dimmed stop: the first shows the pattern's levels x 0.5 (about 1/4.6 of
#: the light for a projector near gamma 2.2), the next x 0.25 (1/21), then x 0.125 (1/98); a
#: further one only while something is still clipped.
DRIVE_STEP = 0.5
#: Dimmed stops at most per capture.
MAX_DIMS = 3
#: Encoded values (0..1) a dimmed frame's pixel needs above the black capture's code at the
#: same stop to measure the ratio, tried in turn until enough pixels pass: well above an
#: 8-bit camera's noise, then what a dark screen in a 12-bit camera's one-period stop leaves
#: (a dimmed diffuse part at a few % of full scale).
RATIO_CODES = (16.0 / 255.0, 4.0 / 255.0)
#: Pixels of a camera channel that must measure the ratio.
MIN_RATIO_PIXELS = 20
#: Pixels next to a clipped one (camera px) left out of the ratio: a webcam's sharpening and
#: JPEG spread a clipped highlight's edge.
CLIP_MARGIN = 2


def single_level(pattern: np.ndarray) -> bool:
    """Whether ``pattern`` (H, W, 3) uint8 has at most one drive triple other than black
    (0, 0, 0), and at least one: a pattern whose light can be dimmed by a measured ratio."""
    flat = np.asarray(pattern).reshape(-1, 3)
    lit = flat[np.any(flat != 0, axis=1)]
    return lit.shape[0] > 0 and bool(np.all(lit == lit[0]))


def dimmed(pattern: np.ndarray, drive: float) -> np.ndarray:
    """``pattern`` (H, W, 3) uint8 with every level scaled by ``drive`` (0..1), rounded:
    (H, W, 3) uint8 (black stays black)."""
    return np.rint(np.asarray(pattern, np.float64) * drive).astype(np.uint8)


def measured_ratio(
    lin: np.ndarray,
    clipped: np.ndarray,
    dim_lin: np.ndarray,
    dim_codes: np.ndarray,
    black: np.ndarray | None,
    black_codes: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The light ratio r (3,) per camera channel of a dimmed capture to its undimmed one
    (module doc), NaN for a channel with fewer than :data:`MIN_RATIO_PIXELS` pixels to
    measure it, and the pixels that measured it (3,) int.

    Args:
        lin: (H, W, 3) float32 the undimmed capture's linear light (any units).
        clipped: (H, W, 3) bool its clipped pixel-channels (not used, nor their neighbours).
        dim_lin: (H, W, 3) float32 the dimmed capture's linear light in the same units.
        dim_codes: (H, W, 3) float the dimmed frame's encoded values 0..1 (well exposed:
            one of :data:`RATIO_CODES` .. CLIP_CODE).
        black: (H, W, 3) float32 the black capture in the same units, or None (0).
        black_codes: (H, W, 3) float the black capture's encoded values 0..1 at the dimmed
            frame's exposure (what it would read there), or None (0): a pixel measures only
            where its dimmed code is one of :data:`RATIO_CODES` above it.
    """
    b = 0.0 if black is None else black.astype(np.float64)
    above = lin.astype(np.float64) - b
    dim_above = dim_lin.astype(np.float64) - b
    kernel = np.ones((2 * CLIP_MARGIN + 1, 2 * CLIP_MARGIN + 1), np.uint8)
    near_clip = cv2.dilate(np.any(clipped, axis=2).astype(np.uint8), kernel) > 0
    out = np.full(3, np.nan)
    counts = np.zeros(3, np.int64)
    signal = dim_codes if black_codes is None else dim_codes - black_codes
    for k in range(lin.shape[2]):
        usable = ~near_clip & (dim_codes[..., k] < CLIP_CODE) & (above[..., k] > 0)
        for low in RATIO_CODES:
            good = usable & (signal[..., k] >= low)
            n = int(np.count_nonzero(good))
            if n >= MIN_RATIO_PIXELS:
                break
        if n < MIN_RATIO_PIXELS:
            continue
        den = float(above[..., k][good].sum())
        num = float(dim_above[..., k][good].sum())
        if den > 0 and num > 0:
            out[k] = num / den
            counts[k] = n
    return out, counts


def weighted_median(values: np.ndarray, weights: np.ndarray) -> float:
    """The median of ``values`` (n,) weighted by ``weights`` (n,) >= 0, over the finite values
    of positive weight: the smallest value with at least half the weight at or below it; NaN
    when there is none."""
    v = np.asarray(values, np.float64)
    w = np.asarray(weights, np.float64)
    keep = np.isfinite(v) & (w > 0)
    if not keep.any():
        return float("nan")
    order = np.argsort(v[keep])
    vs, cum = v[keep][order], np.cumsum(w[keep][order])
    return float(vs[int(np.searchsorted(cum, 0.5 * cum[-1]))])


def fill_clipped(
    lin: np.ndarray,
    clipped: np.ndarray,
    dim_lin: np.ndarray,
    dim_clipped: np.ndarray,
    black: np.ndarray | None,
    ratio: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """``lin`` (H, W, 3) float32 with its ``clipped`` pixel-channels that the dimmed capture
    ``dim_lin`` holds (not ``dim_clipped``, a finite ``ratio`` (3,)) replaced by
    B + (dim_lin - B) / ratio; returns it and the pixel-channels still clipped (bool)."""
    b = np.zeros_like(lin) if black is None else black.astype(np.float32)
    r = np.where(np.isfinite(ratio) & (ratio > 0), ratio, np.nan).astype(np.float32)
    fill = clipped & ~dim_clipped & np.isfinite(r)[None, None, :]
    with np.errstate(invalid="ignore"):
        value = b + (dim_lin.astype(np.float32) - b) / r[None, None, :]
    out = np.where(fill, np.maximum(value, 0.0), lin).astype(np.float32)
    return out, clipped & ~fill


class Dimmer:
    """Recovers what a bracket's captures clip with dimmed copies of the pattern (module
    doc). ``show(pattern) -> not_before`` shows a pattern and returns the clock time from
    which frames show it; ``shortest(frames, not_before, what) -> (codes, rel)`` takes the
    mean of frames at the bracket's least light ((H, W, 3) uint8/uint16 codes, its relative
    exposure); ``response`` linearises the codes (read at each call: the session may
    estimate it after making the dimmer).

    A ratio belongs to the projector and camera, not to the capture: each (drive triple,
    dimmed stop) keeps every ratio measured so far and uses, per camera channel, their median
    weighted by the pixels that measured each (:func:`weighted_median`). A capture whose own
    unclipped part is too small to measure a channel (a fine Gray-code plane, a screen that
    barely reflects that channel) so takes the earlier ones', and one measurement gone wrong
    does not replace the rest however many pixels it had.
    """

    def __init__(
        self,
        show: Callable[[np.ndarray], float],
        shortest: Callable[[int, float, str], tuple[np.ndarray, float]],
        response: Callable[[], Response],
        log: Log,
    ) -> None:
        self.show = show
        self.shortest = shortest
        self.response = response
        self.log = log
        #: captures dimmed, and the pixel-channels their dimmed stops recovered
        self.dimmed = 0
        self.recovered = 0
        #: (drive triple, dimmed stop) -> (ratio in use (3,), pixels that measured it (3,))
        self.known: dict[tuple[tuple[int, ...], int], tuple[np.ndarray, np.ndarray]] = {}
        #: (drive triple, dimmed stop) -> every (ratio (3,), pixels (3,)) measured
        self._measured: dict[tuple[tuple[int, ...], int], list[tuple[np.ndarray, np.ndarray]]]
        self._measured = {}
        self._told_many_levels = False

    def summary(self) -> str:
        """What the dimmed stops did in the capture, for its log."""
        return (
            f"HDR: {self.dimmed} capture(s) clipped in the shortest stop were taken again with "
            f"the projector dimmed ({self.recovered} pixel-channels recovered)"
        )

    def _ratio(
        self, key: tuple[tuple[int, ...], int], ratio: np.ndarray, counts: np.ndarray
    ) -> np.ndarray:
        """The ratio (3,) to use for ``key`` after this measurement (``ratio``, ``counts``
        (3,)): per channel the pixel-weighted median of every measurement of ``key``."""
        seen = self._measured.setdefault(key, [])
        seen.append((np.asarray(ratio, np.float64), np.asarray(counts, np.int64)))
        rs = np.stack([r for r, _ in seen])
        ns = np.stack([n for _, n in seen])
        out = np.array([weighted_median(rs[:, k], ns[:, k]) for k in range(rs.shape[1])])
        self.known[key] = (out, ns.sum(axis=0))
        return out

    def recover(
        self,
        pattern: np.ndarray,
        merged: tuple[np.ndarray, np.ndarray],
        black: np.ndarray | None,
        frames: int,
        what: str,
    ) -> tuple[np.ndarray, np.ndarray]:
        """The capture ``merged`` ((H, W, 3) float32 linear in the bracket's base units, its
        clipped pixel-channels) of ``pattern`` with the clipped pixel-channels recovered from
        up to :data:`MAX_DIMS` dimmed stops of ``frames`` frames each (``black``: the
        stage's black capture in the same units, or None). Returns the same pair; unchanged
        for a pattern of many levels or one with nothing clipped."""
        lin, clipped = merged
        if not clipped.any():
            return lin, clipped
        one = single_level(pattern)
        if not one and not self._told_many_levels:
            self._told_many_levels = True
            self.log(
                f"{what}: clipped in the shortest stop; a pattern of many levels is dimmed "
                "by the ratio of its own unclipped pixels (its levels' ratios differ by the "
                "projector's response: docs/INTERFACES.md, HDR)"
            )
        flat = pattern.reshape(-1, 3)
        triple = tuple(int(v) for v in flat[np.argmax(np.any(flat != 0, axis=1))])
        before = int(np.count_nonzero(clipped))
        ratio = np.full(3, np.nan)
        for level in range(1, MAX_DIMS + 1):
            not_before = self.show(dimmed(pattern, DRIVE_STEP**level))
            codes, rel = self.shortest(frames, not_before, f"{what} (dimmed x{level})")
            dim_lin, dim_clipped = merge_exposures([codes], [rel], self.response())
            top = float(np.iinfo(codes.dtype).max)
            black_codes = (
                None if black is None else self.response().encode(np.clip(black * rel, 0, 1))
            )
            found, counts = measured_ratio(lin, clipped, dim_lin, codes / top, black, black_codes)
            ratio = self._ratio((triple, level), found, counts) if one else found
            lin, clipped = fill_clipped(lin, clipped, dim_lin, dim_clipped, black, ratio)
            if not clipped.any():
                break
        self.dimmed += 1
        self.recovered += before - int(np.count_nonzero(clipped))
        if self.dimmed == 1:
            light = ", ".join("-" if not np.isfinite(r) else f"1/{1 / r:.3g}" for r in ratio)
            self.log(
                f"{what}: clipped in the shortest stop; the projector's drive dimmed "
                f"(x{DRIVE_STEP:g} a step, {level} step(s)): light {light} per camera channel "
                f"as measured where nothing clips, {before - int(np.count_nonzero(clipped))} "
                f"of {before} clipped pixel-channels recovered"
            )
        return lin, clipped
