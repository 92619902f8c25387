"""Phase shifting: sub-pixel projector positions from shifted sinusoids, unwrapped by the
coarse Gray code.

The captures ``phase_col_0`` ... ``phase_col_{N-1}`` show a sinusoid along the projector's
columns, level(u) = F + (255 - F) (1 + cos(2 pi u / P - 2 pi n / N)) / 2 with F the floor
:data:`~viewcomp.calib.io.patterns.PHASE_FLOOR` (:func:`~viewcomp.calib.io.patterns.
phase_patterns`), and ``phase_row_n`` the same along its rows. A camera pixel that sees
projector position u records I_n = A + B cos(phi - 2 pi n / N) with phi = 2 pi u / P, so

    phi = atan2(sum_n I_n sin(2 pi n / N), sum_n I_n cos(2 pi n / N))    (mod 2 pi)
    B = (2 / N) |sum_n I_n exp(2 pi i n / N)|

gives u modulo P to a small fraction of a projector pixel, at any camera resolution that
resolves the period (P = 32 projector px is ~19 camera px for a camera with 0.6 camera px per
projector px), because a pixel that integrates over its area, or blur, averages a sinusoid
into one of the same phase.

**The projector's response.** The light is f(level), not the level: a power law near 2.2
adds harmonics k = 2, 3, ... of phi. With N shifts a harmonic k falls onto the fundamental
only when k = +-1 (mod N); every other cancels in the sums above. So no response has to be
measured: N = 8 shifts leave only harmonics 7 and 9. Measured on a gamma-2.4 response over
one period at 0.1-px steps (the 8-bit patterns included): with levels 0..255, 1.17 px RMS
phase error with N = 3 (harmonic 2 aliases), 0.085 px with N = 4, 0.005 px with N = 8; with
the floor F = 192 the patterns' 8-bit rounding dominates (0.18, 0.045, 0.033 px).

**Unwrapping.** The Gray code's coarse planes (those the camera resolves,
:func:`~viewcomp.calib.geo.graycode.resolved_planes`) place the pixel in an interval of
projector pixels; its centre c is within about half the interval (or one interval at a stripe
edge, where a bit may flip) of the truth. The position is the one of the phase's candidates
u_phi + k P nearest to c: u = u_phi + P round((c - u_phi) / P). This needs no alignment of
the Gray-code intervals with the phase's periods (the classic Gray-code + phase-shift
unwrapping reads k from the code and breaks where the code's edge and the phase's wrap
disagree by a pixel), only that c be within P/2 of the truth; the finest plane kept must
therefore have stripes of at most P/4 (then |c - u| <= P/4 + a pixel at worst). A pixel
whose unwrapped position lies further from c than its interval allows (a bit flipped far
from an edge, a phase garbled by a specular glint) is dropped.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import cv2
import numpy as np

from viewcomp.calib.errors import FitError
from viewcomp.calib.geo.captures import Captures, channel_mean
from viewcomp.calib.geo.graycode import WHOLE_FRACTION, WHOLE_WINDOW, GrayCode
from viewcomp.calib.io.patterns import PHASE_AXES, PHASE_PERIOD, PHASE_SHIFTS, phase_names

# B / (white - black) below which a pixel's phase is not trusted: the sinusoid is not
# resolved there (a pixel half off the frame, a dark spot, a blurred or too coarse camera)
MIN_MODULATION = 0.12


@dataclass(frozen=True)
class PhaseMap:
    """Sub-pixel projector positions per camera pixel (Hc, Wc) from phase shifting.

    ``position`` (Hc, Wc, 2) float64 projector (u, v) in pixels (centres at integers), NaN
    where not decoded; ``ok`` (Hc, Wc) bool where decoded; ``modulation`` (2, Hc, Wc) float32
    B / (white - black) per axis (u, v), 0..~0.6; ``whole`` (Hc, Wc) bool the decoded pixels
    that see the projector's frame whole (not mixed with the unlit surround by blur: their
    phase is unbiased, the ones for a fit); ``planes`` the indices of the Gray-code
    planes used to unwrap; ``stats`` JSON-ready numbers (pixels decoded, dropped as
    inconsistent, the finest stripe kept).
    """

    position: np.ndarray
    ok: np.ndarray
    modulation: np.ndarray
    whole: np.ndarray
    planes: tuple[int, ...]
    stats: dict[str, float | int | list[int]]


def has_phase(caps: Captures, shifts: int = PHASE_SHIFTS) -> bool:
    """Whether the captures hold the phase-shift patterns: False when none is there (a set
    captured before they were added: Gray code alone).

    Raises:
        FitError: some but not all of them are there (naming the first missing).
    """
    names = phase_names(shifts)
    present = [caps.has(n) for n in names]
    if not any(present):
        return False
    if not all(present):
        missing = names[present.index(False)]
        there = names[present.index(True)]
        raise FitError(
            caps.rel(missing),
            f"not found, although other phase-shift captures are there (e.g. {there}): capture "
            f"all {len(names)} phase patterns (phase_col_0 ... phase_row_{shifts - 1}) in the "
            "order of `viewcomp patterns`, or remove them all to calibrate with the Gray code "
            "alone",
        )
    return True


def wrapped_phase(images: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """N >= 3 captures (Hc, Wc) of a sinusoid shifted by 2 pi n / N -> (phase, amplitude):
    phi in [0, 2 pi) (Hc, Wc) float64 and B (Hc, Wc) float64 in the captures' units."""
    n = len(images)
    if n < 3:
        raise ValueError(f"phase shifting needs at least 3 shifts, got {n}")
    delta = 2.0 * np.pi * np.arange(n) / n
    s = sum(np.sin(d) * np.asarray(im, np.float64) for d, im in zip(delta, images, strict=True))
    c = sum(np.cos(d) * np.asarray(im, np.float64) for d, im in zip(delta, images, strict=True))
    phase = np.mod(np.arctan2(s, c), 2.0 * np.pi)
    return phase, (2.0 / n) * np.hypot(s, c)


def coarse_position(bits: np.ndarray, table: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Decode a subset of Gray-code planes into an interval of projector pixels.

    ``bits`` (m, Hc, Wc) bool: the camera's bit per plane; ``table`` (m, size) bool: each
    plane's bit per projector pixel. Returns (centre, half_width), each (Hc, Wc) float64:
    the middle of the projector pixels whose code the camera pixel read and half their extent
    (NaN for a code no projector pixel has).
    """
    m, size = table.shape
    weights = (1 << np.arange(m)).astype(np.int64)
    codes = (table.T.astype(np.int64) * weights).sum(axis=1)  # (size,)
    pos = np.arange(size, dtype=np.float64)
    n_codes = 1 << m
    count = np.bincount(codes, minlength=n_codes)
    lo = np.full(n_codes, np.inf)
    hi = np.full(n_codes, -np.inf)
    np.minimum.at(lo, codes, pos)
    np.maximum.at(hi, codes, pos)
    with np.errstate(invalid="ignore"):
        centre = np.where(count > 0, (lo + hi) / 2.0, np.nan)
        half = np.where(count > 0, (hi - lo) / 2.0, np.nan)
    code = np.tensordot(weights, bits.astype(np.int64), axes=(0, 0))
    return centre[code], half[code]


def _axis_planes(
    caps: Captures,
    gc: GrayCode,
    a: int,
    widths: np.ndarray,
    resolved: np.ndarray,
    period: int,
) -> tuple[np.ndarray, int]:
    """The Gray-code planes of axis ``a`` (0 columns, 1 rows) that unwrap its phase: the
    resolved ones (indices into ``widths``) and the finest stripe width among them (px; the
    axis' projector size where none is resolved).

    Raises:
        FitError: the finest resolved stripe is wider than ``period // 4`` px, so the coarse
            position cannot pick the phase's period.
    """
    planes = np.arange(gc.n_col_bits) if a == 0 else np.arange(gc.n_col_bits, len(widths))
    keep = planes[resolved[planes]]
    table = gc.col_bits if a == 0 else gc.row_bits
    finest_w = int(widths[keep].min()) if keep.size else int(table.shape[1])
    if finest_w > period // 4:
        dropped = planes[~resolved[planes]]
        k = int(dropped[np.argmax(widths[dropped])]) if dropped.size else int(planes[-1])
        raise FitError(
            caps.rel(gc.names[2 * k]),
            f"the camera does not resolve the Gray code's {int(widths[k])}-px stripes "
            f"(contrast {gc.contrast[k]:.2f}), so it cannot place a pixel within "
            f"{period // 4} projector px, as unwrapping the {period}-px phase needs: move "
            "the camera closer or use a camera of higher resolution, focus it, and capture "
            "again",
        )
    return keep, finest_w


def _axis_captures(
    caps: Captures,
    names: list[str],
    on_axis: Callable[[str, np.ndarray], None] | None,
) -> list[np.ndarray]:
    """The channel means (Hc, Wc) of one axis' phase captures ``names``, in shift order;
    ``on_axis`` (see ``decode_phase``) is given the first name and their (Hc, Wc, 3) mean."""
    imgs = []
    total = None
    for n in names:
        img3 = caps.get(n)
        imgs.append(channel_mean(img3))
        total = img3 if total is None else total + img3
    if on_axis is not None and total is not None:
        on_axis(names[0], total / np.float32(len(names)))
    return imgs


def decode_phase(
    caps: Captures,
    gc: GrayCode,
    period: int = PHASE_PERIOD,
    shifts: int = PHASE_SHIFTS,
    on_axis: Callable[[str, np.ndarray], None] | None = None,
) -> PhaseMap:
    """Sub-pixel projector (u, v) per camera pixel: the phase of ``phase_col_*`` and
    ``phase_row_*``, unwrapped by the Gray code's resolved coarse planes (module doc).

    ``on_axis(name, mean)`` sees each axis' captures as they are loaded: ``name`` the first
    (``phase_col_0``, ``phase_row_0``) and ``mean`` (Hc, Wc, 3) their mean, the sinusoids
    cancelling to an evenly lit frame.

    Raises:
        FitError: a missing phase capture, or a camera too coarse for the phase's period (the
            Gray-code planes it resolves do not narrow a pixel down to P/4).
    """
    names = phase_names(shifts)
    white = channel_mean(caps.get("graycode_white"))
    black = channel_mean(caps.get("graycode_black"))
    rng = np.maximum(white - black, 1e-6)
    widths = gc.stripe_widths()
    resolved = gc.resolved()
    position = np.full((*gc.lit.shape, 2), np.nan)
    ok = gc.lit.copy()
    modulation = np.zeros((2, *gc.lit.shape), np.float32)
    used: list[int] = []
    finest: list[int] = []
    inconsistent = 0
    for a in range(len(PHASE_AXES)):
        keep, finest_w = _axis_planes(caps, gc, a, widths, resolved, period)
        table = gc.col_bits if a == 0 else gc.row_bits
        first = 0 if a == 0 else gc.n_col_bits
        used += [int(k) for k in keep]
        finest.append(finest_w)
        centre, half = coarse_position(gc.bits[keep], table[keep - first])
        imgs = _axis_captures(caps, names[a * shifts : (a + 1) * shifts], on_axis)
        phi, amp = wrapped_phase(imgs)
        modulation[a] = amp / rng
        u_phi = phi * (period / (2.0 * np.pi))
        with np.errstate(invalid="ignore"):
            u = u_phi + period * np.rint((centre - u_phi) / period)
            # a flipped bit at a stripe edge moves the centre by about one interval
            fits = np.abs(u - centre) <= 3.0 * half + 2.0
        size = table.shape[1]
        good = (modulation[a] >= MIN_MODULATION) & (u >= -0.5) & (u <= size - 0.5)
        inconsistent += int(np.count_nonzero(ok & good & ~fits))
        ok &= good & fits
        position[..., a] = u
    position[~ok] = np.nan
    near_max = cv2.dilate(rng.astype(np.float32), np.ones((WHOLE_WINDOW, WHOLE_WINDOW), np.uint8))
    whole = ok & (rng >= WHOLE_FRACTION * near_max)
    lit = int(np.count_nonzero(gc.lit))
    stats: dict[str, float | int | list[int]] = {
        "period_px": period,
        "shifts": shifts,
        "decoded_fraction_of_lit": round(float(np.count_nonzero(ok)) / max(lit, 1), 4),
        "inconsistent_fraction_of_lit": round(inconsistent / max(lit, 1), 4),
        "graycode_planes_used": len(used),
        "graycode_planes_dropped": len(widths) - len(used),
        "finest_stripe_used_px": finest,
    }
    return PhaseMap(position, ok, modulation, whole, tuple(used), stats)


def with_phase(gc: GrayCode, pm: PhaseMap) -> GrayCode:
    """The Gray code with the phase's positions: ``column`` / ``row`` the nearest projector
    pixel (-1 where the phase did not decode) and ``subpixel`` the positions themselves."""
    w, h = gc.col_bits.shape[1], gc.row_bits.shape[1]
    uv = np.rint(np.nan_to_num(pm.position, nan=0.0))
    column = np.where(pm.ok, np.clip(uv[..., 0], 0, w - 1), -1).astype(np.int32)
    row = np.where(pm.ok, np.clip(uv[..., 1], 0, h - 1), -1).astype(np.int32)
    return replace(gc, column=column, row=row, subpixel=pm.position)
