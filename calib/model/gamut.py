"""The adaptive tone map's per-pixel math (docs/RUNTIME.md "Adaptive tone map"): the reach of
each projector pixel on the screen, the smooth gain/offset field and the hue-keeping soft
clip. The numpy truth the shader follows (float32, as the GPU computes).

Notation as :func:`~viewcomp.calib.model.reference.tone_terms`: at the eye the screen shows
M y + A for projector light y in [0, 1]^3; u = M^-1 C_w, v = M^-1 1, c = -M^-1 A, so the
target T = g C_w + o (a gain g and an offset o, in camera units) asks for the light
y = g u + o v + c.

- **Reach**: the lowest colour a pixel can show is A (y = 0), the highest M 1 + A (y = 1);
  the greys n (1, 1, 1) it can show are those with n v + c in [0, 1]^3, an interval
  [n_lo, n_hi] (empty when no grey fits: then n_lo > n_hi).
- **Field**: g and o are bilinear in a coarse grid of nodes over the image (``ToneField``),
  so they change only slowly across the screen: edges and local contrast pass through.
- **Soft clip**: the target's luminance Y = k . T (k: Rec. 709, the camera's linear RGB taken
  as linear sRGB, as the evaluation does) is pressed under n_hi with a rational knee over
  the top ``KNEE`` of the range, and T scaled with it (T Y'/Y: the same chromaticity). The
  knee acts on linear light, where the top tenth of a range is a sliver of lightness (L*
  96-100 of a white) and the bottom tenth is a third of it (L* 0-38): a knee there lifted
  every shadow that fitted. Then the chroma, T' - Y' 1, is pressed toward the grey Y' 1 by
  the same knee on the share of it that fits in [0, 1]^3: the hue stays, the saturation
  gives. A target darker than n_lo, or where no grey fits, is clipped per channel as the
  global tone map does: holding it at the grey n_lo lifted shadows and greyed dark colours
  (spectralon, astronaut: 1.10 adapted dE against the per-channel clip's 0.86).
- **Hue weight**: the light is ``hue`` x the soft clip + (1 - ``hue``) x the per-channel
  clip of the light asked for, one weight per field (per shot). Where the screen shows
  nearly every colour the per-channel clip loses less than pressing a colour toward a
  grey that sits on the reach's edge (satin_gold: a warm highlight's blue light went from
  0.43 to 0.97), and with ``hue`` 0 and a uniform field the map is the global rule exactly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Luminance weights (Rec. 709 / sRGB), summing to 1: the grey n (1, 1, 1) has luminance n.
LUMA = np.array([0.2126, 0.7152, 0.0722], np.float32)
#: The soft clip's knee: the top KNEE of a range is compressed toward its end (linear
#: light; content that fits below it is untouched).
KNEE = np.float32(0.1)
#: Below this a value counts as zero (a channel of v, a luminance, a chroma).
TINY = np.float32(1e-6)
#: Greys beyond +-GREY_LIMIT (camera units, full scale 1) are never asked for: the bound of a
#: range that no channel bounds.
GREY_LIMIT = np.float32(1e3)
#: The chroma's share that fits is taken as at most this (beyond 1 / (1 - KNEE) the knee
#: leaves the chroma whole).
SHARE_MAX = np.float32(2.0)


@dataclass(frozen=True)
class ToneField:
    """A smooth tone map: gain and offset at a (ny, nx) grid of nodes, the nodes at the
    image's edges and evenly between (bilinear between them); offsets in camera units.
    ``hue`` in [0, 1]: the soft clip's share against the per-channel clip (module
    docstring)."""

    gain: np.ndarray
    offset: np.ndarray
    hue: float = 1.0

    @classmethod
    def uniform(
        cls, alpha: float, beta: float, nodes: tuple[int, int], hue: float = 1.0
    ) -> ToneField:
        """The global tone map (alpha, beta) as a field on ``nodes`` = (ny, nx); with
        ``hue`` 0 it is the global tone map exactly."""
        return cls(np.full(nodes, alpha, np.float64), np.full(nodes, beta, np.float64), hue)

    @property
    def nodes(self) -> tuple[int, int]:
        """(ny, nx)."""
        return (int(self.gain.shape[0]), int(self.gain.shape[1]))

    def blend(self, other: ToneField, k: float) -> ToneField:
        """self + k (other - self), node by node and the hue weight (the temporal
        smoothing)."""
        return ToneField(
            self.gain + k * (other.gain - self.gain),
            self.offset + k * (other.offset - self.offset),
            self.hue + k * (other.hue - self.hue),
        )


def node_weights(n: int, size: int) -> tuple[np.ndarray, np.ndarray]:
    """For ``size`` pixel centres along an axis with ``n`` nodes (node 0 on the first pixel's
    centre, node n - 1 on the last's): the lower node index i0 (size,) and the weight f of
    node i0 + 1, float32. The shader computes the same from the pixel index."""
    scale = np.float32((n - 1) / max(size - 1, 1))
    x = np.arange(size, dtype=np.float32) * scale
    i0 = np.minimum(np.floor(x).astype(np.int32), max(n - 2, 0))
    return i0, (x - i0.astype(np.float32)).astype(np.float32)


def field_at(field: ToneField, shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """The field's gain and offset at every pixel of an (H, W) grid: two (H, W) float32."""
    h, w = shape
    ny, nx = field.nodes
    out = []
    for nodes in (field.gain, field.offset):
        z = np.asarray(nodes, np.float32)
        if nx == 1 and ny == 1:
            out.append(np.full((h, w), z[0, 0], np.float32))
            continue
        iy, fy = node_weights(ny, h) if ny > 1 else (np.zeros(h, np.int32), np.zeros(h, np.float32))
        ix, fx = node_weights(nx, w) if nx > 1 else (np.zeros(w, np.int32), np.zeros(w, np.float32))
        iy1, ix1 = np.minimum(iy + 1, ny - 1), np.minimum(ix + 1, nx - 1)
        top = z[iy][:, ix] + (z[iy][:, ix1] - z[iy][:, ix]) * fx[None, :]
        bot = z[iy1][:, ix] + (z[iy1][:, ix1] - z[iy1][:, ix]) * fx[None, :]
        out.append((top + (bot - top) * fy[:, None]).astype(np.float32))
    return out[0], out[1]


@dataclass(frozen=True)
class Reach:
    """What each pixel can show at one eye: ``lowest`` = A and ``highest`` = M 1 + A
    (..., 3), and the greys n (1, 1, 1) in [``grey_lo``, ``grey_hi``] (...,), camera units."""

    lowest: np.ndarray
    highest: np.ndarray
    grey_lo: np.ndarray
    grey_hi: np.ndarray


def grey_range(v: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The greys n with n v + c in [0, 1]^3: (n_lo, n_hi) (...,), float32 (module docstring).
    A channel with v = 0 bounds nothing (its light does not change along the greys)."""
    v = v.astype(np.float32)
    c = c.astype(np.float32)
    safe = np.where(np.abs(v) > TINY, v, np.float32(1.0))
    a, b = (0.0 - c) / safe, (1.0 - c) / safe
    lo = np.where(np.abs(v) > TINY, np.minimum(a, b), -GREY_LIMIT).max(axis=-1)
    hi = np.where(np.abs(v) > TINY, np.maximum(a, b), GREY_LIMIT).min(axis=-1)
    return (
        np.clip(lo, -GREY_LIMIT, GREY_LIMIT).astype(np.float32),
        np.clip(hi, -GREY_LIMIT, GREY_LIMIT).astype(np.float32),
    )


def reach(m: np.ndarray, a: np.ndarray) -> Reach:
    """The :class:`Reach` of a screen M (..., 3, 3), A (..., 3) at one eye."""
    m64, a64 = np.asarray(m, np.float64), np.asarray(a, np.float64)
    m_inv = np.linalg.inv(m64)
    lo, hi = grey_range(m_inv.sum(axis=-1), -np.einsum("...ij,...j->...i", m_inv, a64))
    return Reach(a64.astype(np.float32), (m64.sum(axis=-1) + a64).astype(np.float32), lo, hi)


def knee(x: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """x pressed into [lo, hi]: unchanged from lo to the top KNEE of the range, a rational
    knee over that top part (continuous with slope 1 where it starts, tending to hi), held
    at lo below it."""
    span = np.maximum(hi - lo, TINY)
    r = KNEE * span  # > 0: the knee divides by it
    up = np.maximum(x - (hi - r), 0.0)  # how far above the knee's start
    # up / (1 + up / r) written with one division: up r / (r + up) (the shader's form)
    y = np.maximum(x - up + up * r / (r + up), lo)
    return y.astype(np.float32)


def soft_light(
    u: np.ndarray,
    v: np.ndarray,
    c: np.ndarray,
    luma_cw: np.ndarray,
    gain: np.ndarray,
    offset: np.ndarray,
    grey_lo: np.ndarray,
    grey_hi: np.ndarray,
    hue: float = 1.0,
) -> np.ndarray:
    """The projector light of the adaptive tone map, clipped to [0, 1] (module docstring).

    Args:
        u, v, c: (..., 3) float32, :func:`~viewcomp.calib.model.reference.tone_terms`.
        luma_cw: (...,) k . C_w, the white screen's luminance at each pixel.
        gain, offset: (...,) the field at each pixel (:func:`field_at`).
        grey_lo, grey_hi: (...,) :func:`grey_range` of (v, c).
        hue: the field's hue weight in [0, 1].

    Returns:
        (..., 3) float32 light in [0, 1].
    """
    f32 = np.float32
    if hue <= 0.0:  # the per-channel clip alone
        return _asked(u, v, c, gain, offset)
    lum = (gain * luma_cw + offset).astype(f32)
    # pressed where a grey of its luminance fits or lies below it; else clipped per channel
    ok = (grey_lo <= grey_hi) & (lum >= grey_lo)
    lum2 = np.where(ok, knee(lum, grey_lo, np.where(ok, grey_hi, grey_lo)), lum)
    # T' = T Y'/Y keeps the chromaticity (Y' <= Y); a target with no luminance: the grey Y'.
    lit = lum > TINY
    ratio = np.where(lit, lum2 / np.where(lit, lum, f32(1.0)), 0.0)
    grey = (lum2[..., None] * v + c).astype(f32)
    chroma = ((ratio * gain)[..., None] * u + ((ratio * offset - lum2)[..., None]) * v).astype(f32)
    chroma = np.where(lit[..., None], chroma, f32(0.0))
    # The share t of the chroma that keeps every channel in [0, 1]: grey + t chroma, pressed
    # by the knee below that share (at most SHARE_MAX: beyond 1 / (1 - KNEE) it is 1).
    room = np.where(chroma > 0, 1.0 - grey, -grey)
    share = np.where(np.abs(chroma) > TINY, room / np.where(chroma != 0, chroma, 1.0), SHARE_MAX)
    t_max = np.clip(np.min(share, axis=-1), 0.0, SHARE_MAX).astype(f32)
    t = np.where(ok, knee(np.ones_like(t_max), np.zeros_like(t_max), t_max), f32(1.0))
    soft = np.clip(grey + t[..., None] * chroma, 0.0, 1.0)
    if hue >= 1.0:
        return soft.astype(f32)
    return (_asked(u, v, c, gain, offset) * f32(1.0 - hue) + soft * f32(hue)).astype(f32)


def _asked(
    u: np.ndarray, v: np.ndarray, c: np.ndarray, gain: np.ndarray, offset: np.ndarray
) -> np.ndarray:
    """The light the field asks for, clipped per channel to [0, 1] (float32)."""
    return np.clip(gain[..., None] * u + offset[..., None] * v + c, 0.0, 1.0).astype(np.float32)
