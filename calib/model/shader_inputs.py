"""What the shaders read, prepared on the CPU (numpy only): the CPU side of the formula that
the GL compensator (:class:`viewcomp.rt.gl.compensator.Compensator`) and the mpv export
(:mod:`viewcomp.rt.export.mpv`) both need, here once.

- :func:`pixel_texels` (:func:`pixel_texel_blocks`): the pixel method's per-pixel maps as 8
  RGBA float32 texels per pixel, in the order ``pixel_maps`` of ``compensate_core.glsl``
  reads them;
- :func:`inverse_position` (:func:`inverse_scale`): the inverse LUT's squared position;
- :func:`paper_rows`: the paper method's folded matrices;
- :func:`lobe_table`, :func:`inv_pairs`: the lobe and inverse-LUT tables as texels;
- the adaptive tone map (:mod:`~viewcomp.calib.model.gamut`): :func:`gamut_constants` (its
  constants as the shaders' arguments), :func:`field_step` (the nodes' spacing),
  :func:`field_nodes` (the nodes as the shaders' array) and :func:`luma_rows` (each pixel's
  white-screen luminance as a row of the forward light).
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np

from viewcomp.calib.model.gamut import (
    GREY_LIMIT,
    KNEE,
    LUMA,
    SHARE_MAX,
    TINY,
    ToneField,
    node_weights,
)
from viewcomp.calib.model.runtime import RuntimeModel

MAP_TEXELS = 8  # per pixel in pixel_texels


def pixel_texels(model: RuntimeModel) -> np.ndarray:
    """The pixel method's per-pixel values as (H, W, 8, 4) float32 texels, in the order that
    ``pixel_maps`` of compensate_core.glsl reads: texels 0..2 = row i of Ww | Aw[i], 3..5 =
    row i of Wc | Ac[i], 6 = R | the camera's lobe (red), 7 = p.x, p.y (metres; p.z = 0, the
    screen plane) | the camera's lobe (green, blue) (:attr:`RuntimeModel.cam_lobe`).

    Raises:
        ValueError: an array missing, of the wrong shape or not finite, or points off the
            screen plane, naming it.
    """
    h, w = model.shape
    out = np.empty((h, w, MAP_TEXELS, 4), np.float32)  # every slot is written below
    for r0, block in pixel_texel_blocks(model):
        out[r0 : r0 + len(block)] = block
    return out


def pixel_texel_blocks(model: RuntimeModel) -> Iterator[tuple[int, np.ndarray]]:
    """:func:`pixel_texels` a block of rows at a time: (first row, (rows, W, 8, 4) float32),
    the block one array reused (copy or use it before the next). The 128 bytes of a pixel are
    filled while they are in the cache, and a caller that uploads each block never holds
    the whole grid's texels (265 MB at 1080p: their first touch alone cost 0.3 s here).

    Raises:
        ValueError: as :func:`pixel_texels`, before the first block.
    """
    h, w = model.shape
    maps = []
    for mat, amb in (("Ww", "Aw"), ("Wc", "Ac")):
        if getattr(model, mat) is None or getattr(model, amb) is None:
            raise ValueError("pixel method needs Ww, Wc (H, W, 3, 3) and Aw, Ac (H, W, 3)")
        maps += [
            as_f32(getattr(model, mat), (h, w, 3, 3), mat),
            as_f32(getattr(model, amb), (h, w, 3), amb),
        ]
    refl = as_f32(model.refl, (h, w, 3), "refl")
    pos = as_f32(model.pos, (h, w, 3), "pos")
    if np.abs(pos[..., 2]).max(initial=0.0) > 1e-6:
        raise ValueError("pos must lie on the screen plane z = 0 (docs/MODEL.md section 1)")
    as_f32(model.cam_eye, (3,), "cam_eye")
    lobe_table(model)
    lobe = model.cam_lobe
    if not np.all(np.isfinite(lobe)):
        raise ValueError("the camera's lobe is not finite: check refl, pos, cam_eye and lobe")
    step = max(1, (1 << 14) // max(w, 1))
    buf = np.empty((min(step, h), w, MAP_TEXELS, 4), np.float32)
    for r0 in range(0, h, step):
        rows = slice(r0, r0 + step)
        o = buf[: min(step, h - r0)]
        for k in range(2):
            o[:, :, 3 * k : 3 * k + 3, :3] = maps[2 * k][rows]
            o[:, :, 3 * k : 3 * k + 3, 3] = maps[2 * k + 1][rows]
        o[:, :, 6, :3] = refl[rows]
        o[:, :, 7, :2] = pos[rows, :, :2]
        o[:, :, 6, 3] = lobe[rows, :, 0]
        o[:, :, 7, 2:] = lobe[rows, :, 1:]
        yield r0, o


def lobe_table(model: RuntimeModel) -> np.ndarray:
    """The lobe table as (n, 4) float32 texels (RGB | 0), n >= 2, checked."""
    lobe = np.asarray(model.lobe)
    if lobe.ndim != 2 or lobe.shape[1] != 3 or lobe.shape[0] < 2:
        raise ValueError(f"lobe must be (n, 3) with n >= 2, got {lobe.shape}")
    out = np.zeros((lobe.shape[0], 4), np.float32)
    out[:, :3] = as_f32(lobe, lobe.shape, "lobe")
    return out


def inverse_scale(inv_lo: np.ndarray, inv_hi: np.ndarray, n_inv: int) -> np.ndarray:
    """(N - 1)^2 / (hi - lo) per channel, float64 (3,): the inverse LUT's squared position
    t2 per unit of value (``lut_inverse_sq`` in compensate_core.glsl: position sqrt(t2), t2
    in [0, (N - 1)^2])."""
    lo = np.asarray(inv_lo, np.float64)
    span = np.maximum(np.asarray(inv_hi, np.float64) - lo, 1e-12)
    return (n_inv - 1) ** 2 / span


def inverse_position(inv_lo: np.ndarray, inv_hi: np.ndarray, n_inv: int) -> dict[str, np.ndarray]:
    """The pixel method's ``pixel_t2(y, scale, off, lo, hi)`` constants (compensate_core.glsl),
    float64 (3,) each: t2 = clamp(scale y - off, lo, hi) is the squared LUT position of y.

    It equals the reference's clamp of y to [0, 1], then of the position to
    [0, (N - 1)^2], as one clamp: both are increasing, so the inner bounds map to the outer
    ones.
    """
    s = inverse_scale(inv_lo, inv_hi, n_inv)
    lo = np.asarray(inv_lo, np.float64)
    top = float((n_inv - 1) ** 2)
    return {
        "scale": s,
        "off": s * lo,
        "lo": np.clip(-s * lo, 0.0, top),
        "hi": np.clip(s * (1.0 - lo), 0.0, top),
    }


def paper_rows(
    Ww: np.ndarray,
    Wc_inv: np.ndarray,
    inv_lo: np.ndarray,
    inv_hi: np.ndarray,
    n_inv: int,
    alpha: float,
    beta: float,
) -> np.ndarray:
    """The paper method's ``paper_t2`` rows (compensate_core.glsl), (3, 4) float64: row i =
    (A[i], c[i]) with A = diag(s) alpha Wc_inv Ww and c = s (beta Wc_inv 1 - lo), s =
    :func:`inverse_scale`, so that t2 = A fwd(I) + c is the inverse LUT's squared position."""
    s = inverse_scale(inv_lo, inv_hi, n_inv)
    wc_inv = np.asarray(Wc_inv, np.float64)
    out = np.empty((3, 4), np.float64)
    out[:, :3] = s[:, None] * (alpha * (wc_inv @ np.asarray(Ww, np.float64)))
    out[:, 3] = s * (beta * wc_inv.sum(axis=1) - np.asarray(inv_lo, np.float64))
    return out


def inv_pairs(inv_lut: np.ndarray, n: int) -> np.ndarray:
    """(3, N, 2) float32: [c, i] = (inv_lut[i, c], inv_lut[i + 1, c]) (last pair repeats)."""
    lut = as_f32(inv_lut, (n, 3), "inv_lut")
    out = np.empty((3, n, 2), np.float32)
    out[:, :, 0] = lut.T
    out[:, :-1, 1] = lut[1:].T
    out[:, -1, 1] = lut[-1]
    return out


def as_f32(a: Any, shape: tuple[int, ...], name: str) -> np.ndarray:
    """``a`` as a C-contiguous float32 array of exactly ``shape``, all finite; else
    ValueError naming it."""
    arr = np.ascontiguousarray(np.asarray(a, dtype=np.float32))
    if arr.shape != shape:
        raise ValueError(f"{name} must be {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} holds NaN or infinite values")
    return arr


def gamut_constants() -> dict[str, np.ndarray]:
    """The adaptive tone map's constants as the shaders take them (compensate_core.glsl's
    ``soft_light``): ``k`` = (KNEE, TINY, SHARE_MAX) (3,), ``limit`` = GREY_LIMIT
    (1,), ``luma`` the luminance weights (3,); float32, the values of
    :mod:`~viewcomp.calib.model.gamut`."""
    return {
        "k": np.array([KNEE, TINY, SHARE_MAX], np.float32),
        "limit": np.array([GREY_LIMIT], np.float32),
        "luma": LUMA.astype(np.float32),
    }


def field_step(nodes: tuple[int, int], shape: tuple[int, int]) -> np.ndarray:
    """(nx - 1) / (W - 1), (ny - 1) / (H - 1) as float32 (2,): node coordinates per pixel
    along x and y, as :func:`~viewcomp.calib.model.gamut.node_weights` rounds them, for
    ``nodes`` = (ny, nx) on an ``shape`` = (H, W) grid."""
    (ny, nx), (h, w) = nodes, shape
    return np.array([(nx - 1) / max(w - 1, 1), (ny - 1) / max(h - 1, 1)], np.float32)


def field_nodes(field: ToneField) -> np.ndarray:
    """The field's nodes as (ny nx, 2) float32 (gain, offset), row-major (``field_node(i)`` of
    compensate_core.glsl).

    Raises:
        ValueError: a field of no nodes, with non-finite values or a hue weight outside
            [0, 1].
    """
    ny, nx = field.nodes
    if not 0.0 <= float(field.hue) <= 1.0:  # also refuses NaN
        raise ValueError(f"a tone field's hue weight must be in [0, 1], got {field.hue!r}")
    if ny < 1 or nx < 1 or np.shape(field.offset) != (ny, nx):
        raise ValueError(f"a tone field needs gain and offset of one (ny, nx) shape, got {ny}x{nx}")
    out = np.stack([np.ravel(field.gain), np.ravel(field.offset)], axis=1).astype(np.float32)
    if not np.all(np.isfinite(out)):
        raise ValueError("the tone field holds NaN or infinite values")
    return np.ascontiguousarray(out)


def luma_rows(model: RuntimeModel) -> np.ndarray:
    """Per pixel (k^T Ww | k . Aw), (H, W, 4) float32, k = the luminance weights: the white
    screen's luminance for forward light pw is dot(row.xyz, pw) + row.w (the adaptive tone
    map's luma_cw, read from the view cache's path where Ww is not fetched)."""
    h, w = model.shape
    ww = as_f32(model.Ww, (h, w, 3, 3), "Ww").astype(np.float64)
    aw = as_f32(model.Aw, (h, w, 3), "Aw").astype(np.float64)
    k = LUMA.astype(np.float64)
    out = np.empty((h, w, 4), np.float32)
    out[..., :3] = np.einsum("i,hwij->hwj", k, ww)
    out[..., 3] = aw @ k
    return out


def field_columns(field: ToneField, width: int) -> np.ndarray:
    """The field interpolated along x for each row of nodes: (ny, W, 2) float32 (gain,
    offset), [j, x] = z[j, i0] + (z[j, i0 + 1] - z[j, i0]) f_x, the float32 arithmetic of
    :func:`~viewcomp.calib.model.gamut.field_at`'s rows, so that the shader's blend of two
    of them along y (``field_blend_rows`` of compensate_core.glsl) gives its values exactly."""
    ny, nx = field.nodes
    z = field_nodes(field).reshape(ny, nx, 2)
    if nx == 1:
        return np.ascontiguousarray(np.broadcast_to(z, (ny, width, 2)), np.float32)
    ix, fx = node_weights(nx, width)
    ix1 = np.minimum(ix + 1, nx - 1)
    out = z[:, ix] + (z[:, ix1] - z[:, ix]) * fx[None, :, None]
    return np.ascontiguousarray(out, np.float32)
