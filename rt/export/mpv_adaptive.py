"""The adaptive tone map (:mod:`~viewcomp.calib.model.gamut`) in an mpv export for one eye:
what ``mpv_adaptive.glsl`` reads. mpv holds one mapping per export: the field chosen at
export (for ``--tone-from IMAGE``, as ``viewcomp render`` chooses it for that image) is
compiled in as a constant array, and per pixel six texels carry the terms of the soft clip
at that eye: rows of G | a with u = G pw + a = M^-1 C_w (pw the frame's forward-LUT value),
v = M^-1 1, c = -M^-1 A and the white screen's luminance row (k^T Ww | k . Aw).
"""

from __future__ import annotations

import numpy as np

from viewcomp.calib.model.gamut import ToneField
from viewcomp.calib.model.reference import screen_at, tone_terms
from viewcomp.calib.model.runtime import RuntimeModel
from viewcomp.calib.model.shader_inputs import field_nodes, field_step, gamut_constants, luma_rows
from viewcomp.shaders import array_literal, literal, vec_literal

ADAPTIVE_TEXELS = 6  # per pixel: rows 0..2 of G | a, (v, 0), (c, 0), (k^T Ww, k . Aw)


def adaptive_texels(model: RuntimeModel, eye: np.ndarray) -> np.ndarray:
    """The soft clip's per-pixel terms at ``eye`` (3,) metres, (H, W, 6, 4) float64 (module
    docstring), solved in float64 on the CPU (:func:`~viewcomp.calib.model.reference.screen_at`,
    :func:`~viewcomp.calib.model.reference.tone_terms`).

    Raises:
        numpy.linalg.LinAlgError: the screen's mixing is singular somewhere at this eye.
    """
    assert model.Ww is not None and model.Aw is not None  # a pixel model always has them
    m, amb = screen_at(model, np.asarray(eye, np.float32))
    m_inv = np.linalg.inv(m.astype(np.float64))
    a, v, c = tone_terms(m_inv, model.Aw.astype(np.float64), amb.astype(np.float64))
    h, w = model.shape
    out = np.zeros((h, w, ADAPTIVE_TEXELS, 4), np.float64)
    out[:, :, :3, :3] = np.einsum("hwij,hwjk->hwik", m_inv, model.Ww.astype(np.float64))
    out[:, :, :3, 3] = a
    out[:, :, 3, :3] = v
    out[:, :, 4, :3] = c
    out[:, :, 5] = luma_rows(model)
    return out


def adaptive_defines(field: ToneField, grid: tuple[int, int]) -> dict[str, str | int | float]:
    """``mpv_adaptive.glsl``'s ``#define`` values for ``field`` on a (W, H) ``grid``: the
    nodes, their spacing, the hue weight and the soft clip's constants (those of the GL
    compensator)."""
    ny, nx = field.nodes
    g = gamut_constants()
    nodes = [vec_literal(z) for z in field_nodes(field)]
    return {
        "VC_FIELD_NX": nx,
        "VC_FIELD_NY": ny,
        "VC_FIELD_STEP": vec_literal(field_step((ny, nx), (grid[1], grid[0]))),
        "VC_FIELD_INIT": array_literal("vec2", nodes),
        "VC_FIELD_HUE": literal(float(field.hue)),
        "VC_GAMUT_K": vec_literal(g["k"]),
        "VC_GAMUT_LIMIT": literal(float(g["limit"][0])),
    }
