"""Gray code: decoding OpenCV structured_light's planes into projector column and row.

Each plane is captured with its inverse; a bit is their comparison, reliable where the two
differ clearly. :func:`check_planes` holds every plane against the chessboard's prediction,
so a plane out of order or mislabelled is named.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from viewcomp.calib.errors import FitError
from viewcomp.calib.geo.captures import Captures, channel_mean
from viewcomp.calib.geo.framematch import LIT_FRACTION, LIT_PERCENTILE
from viewcomp.calib.io.patterns import graycode_patterns

# white - black below this fraction of its maximum over the 5 x 5 camera pixels around: a
# pixel that the optics mix with the unlit surround (its phase biased by the dark side, its
# Gray-code bits unreliable)
WHOLE_FRACTION = 0.9
WHOLE_WINDOW = 5  # camera px
# above this share of white - black's 97th percentile a pixel is lit wherever it is; between
# LIT_FRACTION and it, only where it sees the frame whole
LIT_BRIGHT = 0.25
BIT_CONTRAST = 0.08  # |pattern - inverse| / (white - black) below which a bit is unreliable
# median |plane - inverse| / (white - black) over the lit pixels at or above which a plane
# counts as resolved: a stripe the camera resolves reads ~0.8-1 away from its edges; one finer
# than the camera's pixels (and optics) averages its light and inverse toward equal
RESOLVED_CONTRAST = 0.35
BIT_AGREEMENT = 0.8  # a Gray-code plane must agree with the chessboard on this share of pixels
RESPONSE_SAMPLES = 60000  # stripe-edge pixels used to check the camera's response


@dataclass(frozen=True)
class GrayCode:
    """The decoded Gray code: per camera pixel (Hc, Wc) the projector ``column`` and ``row``
    (int32, -1 where not decoded), ``lit`` (bool: the projector lights the pixel), the
    per-plane ``bits`` (n_planes // 2, Hc, Wc) bool and ``reliable`` (same shape, bool), and
    ``response_samples``: pixels on a blurred stripe edge, for
    :func:`~viewcomp.calib.geo.camresponse.estimate_response`."""

    column: np.ndarray
    row: np.ndarray
    lit: np.ndarray
    bits: np.ndarray
    reliable: np.ndarray
    names: tuple[str, ...]
    n_col_bits: int
    col_bits: np.ndarray  # (n_col_bits, W) bool: plane k's bit for each projector column
    row_bits: np.ndarray  # (n_row_bits, H) bool
    response_samples: np.ndarray  # (N, 4, 3) linear: plane, inverse, white, black at a pixel
    contrast: np.ndarray  # (n_planes // 2,) median |plane - inverse| / (white - black), lit px
    subpixel: np.ndarray | None = None  # (Hc, Wc, 2) float64 (u, v), NaN where not decoded

    def positions(self) -> np.ndarray:
        """(Hc, Wc, 2) float64 projector (u, v) per camera pixel, NaN where not decoded: the
        sub-pixel positions when phase shifting gave them, else the whole pixels decoded."""
        if self.subpixel is not None:
            return self.subpixel
        ok = self.column >= 0
        uv = np.stack([self.column, self.row], -1).astype(np.float64)
        uv[~ok] = np.nan
        return uv

    def stripe_widths(self) -> np.ndarray:
        """(n_planes // 2,) int: each plane's narrowest stripe in projector pixels (columns
        for the column planes, rows for the row planes)."""
        tables = [*self.col_bits, *self.row_bits]
        return np.array([_narrowest_run(t) for t in tables], np.int64)

    def resolved(self) -> np.ndarray:
        """(n_planes // 2,) bool: the planes the camera resolves (:func:`resolved_planes`)."""
        return resolved_planes(self.contrast, self.stripe_widths(), self.n_col_bits)


def _narrowest_run(bits: np.ndarray) -> int:
    """Length of the shortest run of equal values inside a 1-D bool array (its length when
    it is constant; the runs at both ends count only if they are the only ones)."""
    edges = np.flatnonzero(np.diff(bits.astype(np.int8))) + 1
    if len(edges) == 0:
        return int(bits.size)
    if len(edges) == 1:
        return int(max(edges[0], bits.size - edges[0]))
    return int(np.diff(edges).min())


def resolved_planes(contrast: np.ndarray, widths: np.ndarray, n_col: int) -> np.ndarray:
    """Which Gray-code planes the camera resolves: (n,) bool from each plane's measured
    ``contrast`` (median |plane - inverse| / (white - black) over the lit pixels) and stripe
    ``widths`` (projector px), the first ``n_col`` planes the columns' and the rest the rows'.

    A plane is resolved when its contrast is at least :data:`RESOLVED_CONTRAST`; along each
    axis, once a plane fails every plane with stripes as narrow or narrower is dropped too
    (a finer stripe blurs at least as much), so the planes kept are the coarse ones.
    """
    c = np.asarray(contrast, np.float64)
    w = np.asarray(widths, np.int64)
    out = np.zeros(c.shape, bool)
    for axis in (np.arange(n_col), np.arange(n_col, c.size)):
        if axis.size == 0:
            continue
        ok = c[axis] >= RESOLVED_CONTRAST
        failed = w[axis][~ok]
        limit = failed.max() if failed.size else 0
        out[axis] = ok & (w[axis] > limit)
    return out


def graycode_names(w: int, h: int) -> list[str]:
    """Capture names of the Gray-code planes for a w x h projector (graycode_00 ...)."""
    n = len(graycode_patterns(w, h)[0])
    digits = max(2, len(str(n - 1)))
    return [f"graycode_{k:0{digits}d}" for k in range(n)]


def lit_mask(white: np.ndarray, black: np.ndarray, rel: str) -> tuple[np.ndarray, float]:
    """(Hc, Wc) bool where the projector lights the screen, and white - black's 97th
    percentile. Raises FitError if nothing is lit.

    Lit: white - black above :data:`LIT_BRIGHT` of that percentile, or above
    :data:`~viewcomp.calib.geo.framematch.LIT_FRACTION` of it where the pixel sees the frame
    whole (at least :data:`WHOLE_FRACTION` of its neighbourhood's maximum). A broad lobe lights
    the frame's far sides at 0.18 of the percentile (bluebook), which a quarter alone left out
    of the Gray code (23 of 128 parts of the projector image undecoded at 160x80); the unlit
    surround stays below 0.03 of it; the frame's blurred edge, partly lit, stays out (its bits
    are wrong often enough to pull the lens fit: k2 0.11 instead of 0.02 with it in).

    The 97th, not a higher one: a glossy screen's highlight of the projector's lens (measured
    materials: up to 4 % of the camera image) sets a higher percentile; with the 99.5th the
    mask shrank to the highlight (4.6 % of the image instead of 31 % for green plastic) and
    the Gray code was left undecoded around it."""
    rng = white - black
    top = float(np.percentile(rng, LIT_PERCENTILE))
    if top <= 0.02:
        raise FitError(
            rel,
            f"the projector is not visible (white - black is at most {top:.3f} in linear units): "
            "point the camera at the projected image, raise the exposure, and capture again",
        )
    lit = rng > LIT_BRIGHT * top
    dim = (rng > LIT_FRACTION * top) & ~lit
    if dim.any():
        kernel = np.ones((WHOLE_WINDOW, WHOLE_WINDOW), np.uint8)
        near_max = cv2.dilate(np.ascontiguousarray(rng, np.float32), kernel)
        lit |= dim & (rng >= WHOLE_FRACTION * near_max)
    return lit, top


def decode_graycode(
    caps: Captures,
    projector_size: tuple[int, int],
    on_pair: Callable[[str, np.ndarray], None] | None = None,
) -> GrayCode:
    """Decode OpenCV's Gray-code captures into projector column and row per camera pixel.

    A bit is the comparison of a plane with its inverse, reliable where their difference is
    at least :data:`BIT_CONTRAST` of white - black; a pixel decodes where every bit is.
    ``on_pair(name, plane + inverse)`` sees each pair as it is loaded (the sum is all lit).

    Raises:
        FitError: a missing plane, or a projector too dim to see in graycode_white.
    """
    w, h = projector_size
    planes, _, _ = graycode_patterns(w, h)
    names = graycode_names(w, h)
    n_col = int(np.ceil(np.log2(w)))
    n_pairs = len(planes) // 2
    white = channel_mean(caps.get("graycode_white"))
    black = channel_mean(caps.get("graycode_black"))
    rng = white - black
    lit, top = lit_mask(white, black, caps.rel("graycode_white"))
    bits = np.zeros((n_pairs, *rng.shape), bool)
    reliable = np.zeros((n_pairs, *rng.shape), bool)
    floor = np.maximum(rng, 0.05 * top)
    white3, black3 = caps.get("graycode_white"), caps.get("graycode_black")
    samples = []
    contrast = np.zeros(n_pairs)
    per_pair = RESPONSE_SAMPLES // max(n_pairs, 1)
    for k in range(n_pairs):
        pos3, neg3 = caps.get(names[2 * k]), caps.get(names[2 * k + 1])
        pos, neg = channel_mean(pos3), channel_mean(neg3)
        diff = pos - neg
        bits[k] = diff > 0
        reliable[k] = np.abs(diff) >= BIT_CONTRAST * floor
        contrast[k] = float(np.median(np.abs(diff)[lit] / floor[lit]))
        # pixels the optics blur across a stripe edge see part of each: response samples
        t = (pos - black) / floor
        ys, xs = np.nonzero(lit & (t > 0.15) & (t < 0.85))
        step = max(1, int(np.ceil(len(xs) / max(per_pair, 1))))
        ys, xs = ys[::step], xs[::step]
        samples.append(np.stack([pos3[ys, xs], neg3[ys, xs], white3[ys, xs], black3[ys, xs]], 1))
        if on_pair is not None:
            on_pair(names[2 * k], pos3 + neg3)
    col_bits = np.stack([planes[2 * k][0, :, 0] > 0 for k in range(n_col)])
    row_bits = np.stack([planes[2 * k][:, 0, 0] > 0 for k in range(n_col, n_pairs)])
    ok = lit & reliable.all(axis=0)
    column = _lut_decode(bits[:n_col], col_bits)
    row = _lut_decode(bits[n_col:], row_bits)
    ok &= (column >= 0) & (row >= 0)
    column = np.where(ok, column, -1).astype(np.int32)
    row = np.where(ok, row, -1).astype(np.int32)
    return GrayCode(
        column,
        row,
        lit,
        bits,
        reliable,
        tuple(names),
        n_col,
        col_bits,
        row_bits,
        np.concatenate(samples) if samples else np.zeros((0, 4, 3), np.float32),
        contrast,
    )


def _lut_decode(bits: np.ndarray, table: np.ndarray) -> np.ndarray:
    """Bits (n, Hc, Wc) -> index into the table's columns (-1 for a code no column has)."""
    n, size = table.shape
    weights = (1 << np.arange(n)).astype(np.int64)
    lut = np.full(1 << n, -1, np.int64)
    lut[(table.T.astype(np.int64) * weights).sum(axis=1)] = np.arange(size)
    code = np.tensordot(weights, bits.astype(np.int64), axes=(0, 0))
    return lut[code]


def check_planes(
    gc: GrayCode,
    caps: Captures,
    predicted: np.ndarray,
    region: np.ndarray,
    planes: Sequence[int] | None = None,
) -> dict[str, float]:
    """Each Gray-code plane against the chessboard's prediction of the projector coordinates.

    ``predicted`` (Hc, Wc, 2) projector (u, v) from the chessboard, trusted in ``region``;
    ``planes`` the plane indices to check (None: all; the planes a decoder drops as
    unresolved say nothing of the order). Returns the agreement per plane; raises FitError
    naming a plane that disagrees.
    """
    w, h = gc.col_bits.shape[1], gc.row_bits.shape[1]
    margin = 0.75
    agreement: dict[str, float] = {}
    for k in range(gc.bits.shape[0]) if planes is None else planes:
        is_col = k < gc.n_col_bits
        table = gc.col_bits[k] if is_col else gc.row_bits[k - gc.n_col_bits]
        coord = predicted[..., 0] if is_col else predicted[..., 1]
        size = w if is_col else h
        sel = region & gc.lit
        c = coord[sel]
        lo = np.clip(np.rint(c - margin), 0, size - 1).astype(np.int64)
        mid = np.clip(np.rint(c), 0, size - 1).astype(np.int64)
        hi = np.clip(np.rint(c + margin), 0, size - 1).astype(np.int64)
        same = (table[lo] == table[mid]) & (table[mid] == table[hi])
        if np.count_nonzero(same) < 50:
            continue
        # an unreliable bit (plane and "inverse" alike) counts against the plane too
        bit = gc.bits[k][sel][same]
        sure = gc.reliable[k][sel][same]
        expected = table[mid][same]
        agree = float(np.mean(sure & (bit == expected)))
        inverted = float(np.mean(sure & (bit != expected)))
        agreement[gc.names[2 * k]] = round(agree, 4)
        if agree < BIT_AGREEMENT:
            a, b = caps.rel(gc.names[2 * k]), caps.rel(gc.names[2 * k + 1])
            what = "column" if is_col else "row"
            if inverted > BIT_AGREEMENT:
                reason = (
                    f"{a} and {b} look swapped (bit {k} of the projector {what}s is inverted "
                    f"on {inverted:.0%} of the pixels)"
                )
            else:
                reason = (
                    f"{a} does not show bit {k} of the projector {what}s where the chessboard "
                    f"says it should (agreement {agree:.0%})"
                )
            raise FitError(
                a,
                f"{reason}: the Gray-code captures are out of order or mislabelled, or the "
                "camera moved after the chessboard; capture them again in the order of "
                "`viewcomp patterns` (graycode_00, graycode_01, ...)",
            )
    return agreement
