"""Compact storage of the per-pixel method's maps in a bundle: error-bounded, deflated.

One screen's model is W (H, W, 3, 3) and A (H, W, 3) in float32, 48 bytes a pixel, and
deflate gains little on float32 noise: a 3840x2160 bundle was 911 MB. Half floats or a
reduced resolution are not enough: with a relative error of 5e-4 in W (float16) the
compensated output of a dark channel next to a bright one moves by up to 10 levels, because
the inverse response is steep near black; W~ at half resolution, up to 44 levels
(docs/BENCHMARKS.md, "Native resolutions"). So each map is stored as integers with an
error bound, in the form that compresses best:

- W = W~ diag(D) is split into the gain D (H, W, 3), the diagonal of W (W~'s diagonal is
  1), which is noisy (the gray capture, per pixel), and the six off-diagonal entries of
  W~ = W diag(D)^-1, which are smooth (the colour patterns' ratios, blurred);
- each component c becomes q = round(a_c / step_c), step_c = 2 * tol * median(|a_c|): an
  error of at most tol times the component's typical size;
- smooth components go through the 2-D Lorenzo predictor, r[y, x] = q[y, x] - q[y-1, x] -
  q[y, x-1] + q[y-1, x-1] (0 outside the grid), exact on integers, leaving small numbers;
  noisy ones are stored as they are (a predictor would add the neighbours' noise);
- the int32 integers are split into byte planes (4, H, W, C), which deflate compresses well
  (the high planes are nearly constant).

Decoding is two cumulative sums (or none) and one multiplication per component. A component
whose integers would not fit in int32 keeps its float32 bytes instead (flagged by a step of
0), so any map round-trips.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

#: The largest error of a stored value, relative to its component's median magnitude: the
#: gain D and the ambient A (noisy, and A is what a dark pixel shows), and W~'s off-diagonal
#: entries (smooth). With these the reference's compensated output stays within 1 level of
#: the float32 maps' in all but a few ill-conditioned pixels (docs/BENCHMARKS.md).
REL_TOL = 2e-6
MIX_REL_TOL = 5e-6

#: W~'s off-diagonal entries in the row-major flattening of a 3x3 matrix.
_OFF = [1, 2, 3, 5, 6, 7]

#: Residuals are int32; integers up to this keep every Lorenzo residual (a sum of four) in it.
_Q_MAX = (1 << 29) - 1


def encode_map(
    a: np.ndarray, rel_tol: float = REL_TOL, predict: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    """Encode a per-pixel map (H, W, ...) of floats with the error bound ``rel_tol``;
    ``predict``: the Lorenzo predictor (smooth maps) or the integers as they are (noise).

    Returns:
        (planes, step): planes (4, H, W, C) uint8, the little-endian bytes of the int32
        residuals (or of the float32 values, for a component with step 0), C the product of
        the trailing axes; step (C,) float64, each component's quantisation step, negative
        for integers stored without the predictor.
    """
    a = np.asarray(a)
    h, w = a.shape[:2]
    flat = a.reshape(h, w, -1)
    n = flat.shape[2]
    planes = np.empty((4, h, w, n), np.uint8)
    step = np.zeros(n)
    for c in range(n):
        comp = flat[..., c].astype(np.float64)
        typical = float(np.median(np.abs(comp)))
        s = 2.0 * rel_tol * typical
        peak = float(np.max(np.abs(comp), initial=0.0))
        if s > 0 and np.isfinite(peak) and peak / s <= _Q_MAX:
            q = np.rint(comp / s).astype(np.int64)
            r = q.copy()
            if predict:
                r[1:] -= q[:-1]
                r[:, 1:] -= q[:, :-1]
                r[1:, 1:] += q[:-1, :-1]
            out = r.astype("<i4")
            step[c] = s if predict else -s
        else:  # zero, or too wide a range for int32: the float32 values themselves
            out = comp.astype("<f4")
        planes[..., c] = np.moveaxis(out.view(np.uint8).reshape(h, w, 4), -1, 0)
    return planes, step


def decode_map(planes: np.ndarray, step: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """The float32 map of ``shape`` (H, W, ...) that :func:`encode_map` stored.

    Raises:
        ValueError: planes or step that do not fit ``shape``, or a step not finite.
    """
    h, w = shape[:2]
    n = int(np.prod(shape[2:], dtype=np.int64))
    if planes.shape != (4, h, w, n) or planes.dtype != np.uint8 or step.shape != (n,):
        raise ValueError(f"planes {planes.dtype} {planes.shape}, step {step.shape} for {shape}")
    if not np.all(np.isfinite(step)):
        raise ValueError("quantisation steps must be finite")
    out = np.empty((h, w, n), np.float32)
    for c in range(n):
        raw = np.ascontiguousarray(np.moveaxis(planes[..., c], 0, -1)).view("<i4")[..., 0]
        if step[c] > 0:
            # int32 sums: every partial sum is a difference of two stored integers, within
            # int32 (|q| <= 2^29); a damaged file can only make them wrap, never non-finite.
            q = np.cumsum(np.cumsum(raw, axis=0, dtype=np.int32), axis=1, dtype=np.int32)
            out[..., c] = q * step[c]
        elif step[c] < 0:
            out[..., c] = raw * -step[c]
        else:
            out[..., c] = raw.view("<f4")
    return out.reshape(shape)


def encode_screen(
    prefix: str, w_map: np.ndarray, a_map: np.ndarray
) -> Iterator[tuple[str, np.ndarray]]:
    """One screen's model as (name, array) pairs for the bundle, made one at a time (for
    :func:`~viewcomp.calib.io.bundle.save_bundle`), each with its ``_step`` (C,): for prefix "w"
    (the white screen; "c": the real one) ``pixel.Ww.gain`` (4, H, W, 3), ``pixel.Ww.mix``
    (4, H, W, 6) and ``pixel.Aw`` (4, H, W, 3), uint8 byte planes (:func:`encode_map`).

    Args:
        prefix: "w" or "c".
        w_map: W (H, W, 3, 3); a_map: A (H, W, 3); linear camera units.
    """
    h, w = w_map.shape[:2]
    gain = np.ascontiguousarray(np.einsum("hwjj->hwj", w_map), np.float32)
    planes, step = encode_map(gain, REL_TOL, predict=False)
    yield f"pixel.W{prefix}.gain", planes
    yield f"pixel.W{prefix}.gain_step", step
    # W~ = W diag(D)^-1; a gain of exactly 0 (a dead pixel of the white screen) leaves its
    # column's entries at 0, which D = 0 multiplies back to 0 anyway.
    safe = np.where(gain != 0, gain, np.float32(1.0))
    del gain, planes
    mix = np.empty((h, w, len(_OFF)), np.float32)
    for k, flat in enumerate(_OFF):
        i, j = divmod(flat, 3)
        mix[..., k] = w_map[..., i, j] / safe[..., j]
    del safe
    planes, step = encode_map(mix, MIX_REL_TOL, predict=True)
    del mix
    yield f"pixel.W{prefix}.mix", planes
    yield f"pixel.W{prefix}.mix_step", step
    del planes
    planes, step = encode_map(a_map, REL_TOL, predict=True)
    yield f"pixel.A{prefix}", planes
    yield f"pixel.A{prefix}_step", step


def decode_screen(arrays: dict[str, np.ndarray], prefix: str) -> tuple[np.ndarray, np.ndarray]:
    """(W (H, W, 3, 3), A (H, W, 3)) float32 from :func:`encode_screen`'s arrays.

    Raises:
        KeyError: an array missing; ValueError: arrays that do not fit together.
    """
    name = f"pixel.W{prefix}"
    h, w = arrays[f"{name}.gain"].shape[1:3]
    gain = decode_map(arrays[f"{name}.gain"], arrays[f"{name}.gain_step"], (h, w, 3))
    mix = decode_map(arrays[f"{name}.mix"], arrays[f"{name}.mix_step"], (h, w, len(_OFF)))
    a_map = decode_map(arrays[f"pixel.A{prefix}"], arrays[f"pixel.A{prefix}_step"], (h, w, 3))
    w_map = np.empty((h, w, 3, 3), np.float32)
    for i in range(3):
        w_map[..., i, i] = gain[..., i]
    for k, flat in enumerate(_OFF):
        i, j = divmod(flat, 3)
        w_map[..., i, j] = mix[..., k] * gain[..., j]
    return w_map, a_map
