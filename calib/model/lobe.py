"""The tabulated specular lobe: its coordinate on the screen and its lookup (docs/MODEL.md
section 4).

The lobe is a table of ``n`` RGB values (units of the specular ratio s: the real screen's
light relative to the white screen's) sampled uniformly in the coordinate

    t = sqrt(1 - cos(angle)),  t in [0, 1] for angles 0..90 degrees,

where the angle is, per screen point p and eye E, either between the normal N and the half
vector H = normalize(Y + V) (``half``: microfacet lobes) or between the mirror direction R and
V (``mirror``: Phong lobes), with Y the unit vector to the projector and V = normalize(E - p).
Near the peak t is proportional to the angle (t ~ angle / sqrt(2)), so a uniform table resolves
a one-degree spike as finely as the tail. The lookup interpolates linearly and holds the end
values outside [0, 1]; the fit (:mod:`viewcomp.calib.fit.lobe`) puts the diffuse level (zero)
at the far end.

These two functions are the one source of the lobe's numbers: the fit, the numpy reference,
the GL compensator (through ``RuntimeModel.cam_lobe``) and, in GLSL, ``lobe_value`` of
compensate_core.glsl (the same arithmetic) use them.
"""

from __future__ import annotations

import numpy as np

#: Entries of the lobe table: 1024 over t in [0, 1] is a step of ~0.08 degrees near the peak.
LOBE_N = 1024

#: Pixels per block of rows when :func:`lobe_position` takes a whole grid.
_BLOCK_PIXELS = 1 << 18

#: The two parametrisations, by name; ``half`` is stored as ``RuntimeModel.lobe_half = True``.
LOBE_PARAMS = ("half", "mirror")


def lobe_position(
    refl: np.ndarray, pos: np.ndarray, eye: np.ndarray, half: bool, dtype: type = np.float32
) -> np.ndarray:
    """The lobe coordinate t = sqrt(1 - cos angle) of each screen point seen from ``eye``.

    Args:
        refl: (..., 3) unit mirror directions R (the projector's ray reflected about N = +z).
        pos: (..., 3) screen points in metres (z = 0).
        eye: (3,) the eye (or camera) in metres, z > 0.
        half: the angle between N and H (True) or between R and V (False).
        dtype: float32 (the runtime's arithmetic) or float64 (the fit's).

    Returns:
        (...) t in [0, sqrt(2)]: 0 at the mirror direction, 1 at 90 degrees.
    """
    refl, pos = np.asarray(refl), np.asarray(pos)
    if refl.ndim == 3 and refl.shape[0] > 1 and refl.size > 3 * _BLOCK_PIXELS:
        # A whole grid: one block of rows at a time, so the temporaries (several (..., 3)
        # arrays) stay tens of MB at 3840x2160; the result is the same per pixel.
        out: np.ndarray = np.empty(refl.shape[:-1], dtype)
        step = max(1, _BLOCK_PIXELS // refl.shape[1])
        for r0 in range(0, refl.shape[0], step):
            rows = slice(r0, r0 + step)
            out[rows] = lobe_position(refl[rows], pos[rows], eye, half, dtype)
        return out
    r: np.ndarray = np.asarray(refl, dtype)
    v: np.ndarray = np.asarray(eye, dtype) - np.asarray(pos, dtype)
    v = v / np.linalg.norm(v, axis=-1, keepdims=True)
    if half:
        # Y = R mirrored about N = +z: (-R.x, -R.y, R.z); cos = H.z = (Y + V).z / |Y + V|.
        hx, hy, hz = v[..., 0] - r[..., 0], v[..., 1] - r[..., 1], v[..., 2] + r[..., 2]
        c = hz / np.sqrt(hx * hx + hy * hy + hz * hz)
    else:
        c = np.sum(r * v, axis=-1)
    return np.sqrt(np.maximum(dtype(1.0) - c, dtype(0.0))).astype(dtype)


def lobe_lookup(table: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The lobe at coordinates t: linear interpolation in the (n, 3) table, ends held.

    Args:
        table: (n, 3) lobe values at t = k / (n - 1), n >= 2.
        t: (...) coordinates (any real; clamped to [0, 1]).

    Returns:
        (..., 3) in the table's dtype.
    """
    tab = np.asarray(table)
    n = tab.shape[0]
    dt = tab.dtype.type
    x = np.clip(np.asarray(t, tab.dtype), dt(0.0), dt(1.0)) * dt(n - 1)
    i0 = np.minimum(np.floor(x).astype(np.int32), n - 2)
    f = (x - i0.astype(tab.dtype))[..., None]
    a = tab[i0]
    return (a + (tab[i0 + 1] - a) * f).astype(tab.dtype)
