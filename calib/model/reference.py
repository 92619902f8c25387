"""The numpy reference of the per-frame compensation (docs/RUNTIME.md).

This is the ground truth that the GLSL shader must match. It is plain and exact on purpose:
no caching, no tricks, float32 like the GPU.

Conventions: state arrays are (H, W, C), row 0 at the top of the projector image. Frames in
and out are 8-bit encoded RGB (0..255). Everything in between is linear light in the
calibration camera's units (0..1 = the camera's full scale).
"""

from __future__ import annotations

import numpy as np

from viewcomp.calib.model.gamut import LUMA, ToneField, field_at, grey_range, soft_light
from viewcomp.calib.model.lobe import lobe_lookup, lobe_position
from viewcomp.calib.model.runtime import RuntimeModel
from viewcomp.calib.world.audience import Audience

#: Where the viewer is: one eye (3,) metres, or an :class:`Audience` of several.
View = np.ndarray | Audience


def lut_forward(lut: np.ndarray, levels: np.ndarray) -> np.ndarray:
    """Linear interpolation in a (256, 3) LUT at fractional levels (..., 3) in 0..255."""
    t = np.clip(levels, 0.0, 255.0).astype(np.float32)
    i0 = np.minimum(np.floor(t).astype(np.int32), 254)
    f = t - i0
    ch = np.arange(3)
    a = lut[i0, ch]
    b = lut[i0 + 1, ch]
    return (a + (b - a) * f).astype(np.float32)


def lut_inverse(lut: np.ndarray, lo: np.ndarray, hi: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Linear interpolation in an (N, 3) inverse LUT on [lo, hi]; returns 0..1.

    The LUT is sampled uniformly in sqrt((y - lo) / (hi - lo)): responses are close to power
    laws, whose inverse is steep near black, and the square root spreads the dark levels
    over as many samples as the bright ones (a uniform LUT was off by up to 4 levels there).
    """
    n = lut.shape[0]
    span = np.maximum(hi - lo, np.float32(1e-12)).astype(np.float32)
    x = np.clip((values - lo) / span, 0.0, 1.0).astype(np.float32)
    t = np.sqrt(x) * np.float32(n - 1)
    i0 = np.minimum(np.floor(t).astype(np.int32), n - 2)
    f = t - i0
    ch = np.arange(3)
    a = lut[i0, ch]
    b = lut[i0 + 1, ch]
    return (a + (b - a) * f).astype(np.float32)


def lut_inverse_forward(
    lut: np.ndarray, lo: np.ndarray, hi: np.ndarray, levels01: np.ndarray
) -> np.ndarray:
    """The function :func:`lut_inverse` inverts: the linear value (..., 3) whose inverse-LUT
    output is ``levels01`` (0..1), by linear interpolation in the same samples (the LUT
    increases along its first axis; a flat stretch gives its first sample)."""
    n = lut.shape[0]
    y = lo[None, :] + (hi - lo)[None, :] * ((np.arange(n) / (n - 1)) ** 2)[:, None]
    out = np.empty(levels01.shape, np.float32)
    for c in range(3):
        out[..., c] = np.interp(levels01[..., c], lut[:, c], y[:, c])
    return out


def lobe_change(model: RuntimeModel, eye: np.ndarray) -> np.ndarray:
    """ds(x) = lobe(t_eye(x)) - lobe(t_cam(x)), the specular ratio's change from the
    calibration camera to ``eye``: (H, W, 3) float32."""
    t = lobe_position(model.refl, model.pos, eye, model.lobe_half)
    return (lobe_lookup(np.asarray(model.lobe, np.float32), t) - model.cam_lobe).astype(np.float32)


def white_response(model: RuntimeModel, frame: np.ndarray) -> np.ndarray:
    """C_w: what the white screen shows for an 8-bit frame (H, W, 3), linear camera units."""
    pw = lut_forward(model.fwd_lut, frame.astype(np.float32))
    if model.method == "pixel":
        return np.einsum("hwij,hwj->hwi", model.Ww, pw) + model.Aw
    return pw @ model.Ww.T


def screen_at(model: RuntimeModel, eye: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The real screen seen from ``eye`` (pixel method): it shows M(x) f(I) + A(x) there.

    M = Wc + diag(ds) Ww and A = Ac + ds (eta Aw): the lobe's change scales the white
    screen's light, and the share eta (``lobe_black``) of its black level that is the
    projector's leak (room light comes from elsewhere). Returns M (H, W, 3, 3) and A
    (H, W, 3), float32.
    """
    assert model.Wc is not None and model.Aw is not None and model.Ac is not None  # pixel
    ds = lobe_change(model, eye)
    leak = np.asarray(model.lobe_black, np.float32) * model.Aw
    return model.Wc + ds[..., :, None] * model.Ww, model.Ac + ds * leak


def predict_view(model: RuntimeModel, levels: np.ndarray, eye: np.ndarray) -> np.ndarray:
    """What the real screen shows, seen from ``eye``, when the projector shows ``levels``:
    the model's forward prediction, linear camera units (H, W, 3) float32 (0..1 = the
    calibration camera's full scale; :func:`white_response` is the same for the white screen).

    The inverse of :func:`compensate` for each method, through the same helpers:

    - ``pixel``: M(x; eye) f(I) + A(x; eye), with M and A from :func:`screen_at` (the
      specular lobe as seen from ``eye``) and f the forward LUT;
    - ``paper``: W~_c rho_c(I), with W~_c = ``Wc_inv``^-1 and rho_c the inverse of the inverse
      LUT, both of the model's own eye (a paper model is made for one eye; ``eye`` must be
      that one).

    Args:
        model: the runtime model of one method, on an (H, W) projector grid.
        levels: (H, W, 3) projector levels 0..255 (uint8 or float).
        eye: (3,) eye position in metres.
    """
    lv = np.asarray(levels, np.float32)
    if lv.shape[:2] != model.shape or lv.ndim != 3 or lv.shape[2] != 3:
        raise ValueError(f"levels must be {(*model.shape, 3)}, got {lv.shape}")
    if model.method == "pixel":
        light = lut_forward(model.fwd_lut, lv)
        m, a = screen_at(model, eye)
        return (np.einsum("hwij,hwj->hwi", m, light) + a).astype(np.float32)
    y = lut_inverse_forward(model.inv_lut, model.inv_lo, model.inv_hi, lv / np.float32(255.0))
    assert model.Wc_inv is not None  # a paper model always has it
    wc = np.linalg.inv(model.Wc_inv.astype(np.float64)).astype(np.float32)
    return (y @ wc.T).astype(np.float32)


def tone_terms(
    m_inv: np.ndarray, white: np.ndarray, ambient: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The projector light a tone map (alpha, beta) asks for, as alpha u + beta v + c.

    With the target T = alpha C_w + beta and the screen M f + A, the light is
    f = M^-1 (T - A) = alpha M^-1 C_w + beta M^-1 1 - M^-1 A. One source for the tone map's
    choice (docs/MODEL.md), the GL view cache's CPU side and the evaluation's oracle.

    Args:
        m_inv: (..., 3, 3) inverse of the screen's mixing at the eye.
        white: (..., 3) C_w, what the white screen shows (linear camera units).
        ambient: (..., 3) A, the screen's ambient term (same units).

    Returns:
        u = M^-1 C_w, v = M^-1 1, c = -M^-1 A, each (..., 3), in the dtype of ``m_inv``.
    """
    u = np.einsum("...ij,...j->...i", m_inv, white)
    v = m_inv.sum(axis=-1)
    c = -np.einsum("...ij,...j->...i", m_inv, ambient)
    return u, v, c


def audience_normal(
    model: RuntimeModel, audience: Audience
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The normal equations of the audience's least squares (pixel method, docs/MODEL.md
    section 6): the light y minimising sum_k w_k |M_k y + A_k - T|^2 solves N y = S T - q
    with N = sum_k w_k M_k^T M_k, S = sum_k w_k M_k^T and q = sum_k w_k M_k^T A_k, M_k and
    A_k the screen at eye k (:func:`screen_at`). Summed in float32 in the viewers' order,
    as the shader does.

    Returns:
        N (H, W, 3, 3), S (H, W, 3, 3), q (H, W, 3), float32.
    """
    h, w = model.shape
    n = np.zeros((h, w, 3, 3), np.float32)
    s = np.zeros((h, w, 3, 3), np.float32)
    q = np.zeros((h, w, 3), np.float32)
    for eye, weight in zip(audience.eyes, audience.weights.astype(np.float32), strict=True):
        m, a = screen_at(model, eye)
        mt = np.swapaxes(m, -1, -2)
        n += weight * (mt @ m)
        s += weight * mt
        q += weight * np.einsum("hwij,hwj->hwi", mt, a)
    return n, s, q


def audience_solve(model: RuntimeModel, audience: Audience) -> tuple[np.ndarray, np.ndarray]:
    """The audience's light as a map of the target: y = P T - d with P = N^-1 S and
    d = N^-1 q (:func:`audience_normal`); one viewer: P = M^-1, d = M^-1 A (the same in
    exact arithmetic). Returns P (H, W, 3, 3) and d (H, W, 3), float32."""
    n, s, q = audience_normal(model, audience)
    n_inv = np.linalg.inv(n)
    return (n_inv @ s).astype(np.float32), np.einsum("hwij,hwj->hwi", n_inv, q).astype(np.float32)


def target_to_projector(model: RuntimeModel, target: np.ndarray, eye: View) -> np.ndarray:
    """Solve for the projector signal that shows ``target`` (H, W, 3) at ``eye``.

    ``eye``: one eye (3,) metres, or an :class:`Audience`: with several viewers (pixel
    method) the weighted least squares of :func:`audience_normal`; an audience of one is
    exactly the one eye's solve.

    Returns the value fed to the inverse LUT, before clamping to the LUT domain: linear
    projector light Pc for ``pixel`` (valid range 0..1), decoupled luminance C~_c for
    ``paper`` (valid range [inv_lo, inv_hi]).
    """
    if isinstance(eye, Audience) and len(eye) == 1:
        eye = eye.eyes[0]
    if model.method == "pixel" and isinstance(eye, Audience):
        n, s, q = audience_normal(model, eye)
        rhs = np.einsum("hwij,hwj->hwi", s, target) - q
        return np.linalg.solve(n, rhs[..., None])[..., 0].astype(np.float32)
    if isinstance(eye, Audience):
        raise ValueError("an audience of several viewers needs the pixel method")
    if model.method == "pixel":
        m, a = screen_at(model, eye)
        return np.linalg.solve(m, (target - a)[..., None])[..., 0].astype(np.float32)
    assert model.Wc_inv is not None  # a paper model always has it
    return (target @ model.Wc_inv.T).astype(np.float32)


def compensate(
    model: RuntimeModel,
    frame: np.ndarray,
    eye: View,
    alpha: float,
    beta: float,
    identity: bool = False,
    field: ToneField | None = None,
) -> np.ndarray:
    """The per-pixel formula of docs/RUNTIME.md on the CPU.

    Args:
        model: the runtime model of one method, on an (H, W) projector grid.
        frame: (H, W, 3) uint8, encoded RGB 0..255, already at the projector's resolution.
        eye: (3,) eye position in metres (world frame of docs/MODEL.md), or an
            :class:`Audience` (pixel method; :func:`target_to_projector`).
        alpha, beta: tone map C_c = alpha C_w + beta (Eq. 21), linear camera units.
        identity: pass the frame through unchanged (same quantisation path).
        field: the adaptive tone map (pixel method, one eye; :mod:`~viewcomp.calib.model.gamut`)
            in place of (alpha, beta), which are then unused.

    Returns:
        (H, W, 3) uint8, the image to project.
    """
    if frame.shape[:2] != model.shape or frame.ndim != 3 or frame.shape[2] != 3:
        raise ValueError(f"frame must be {(*model.shape, 3)}, got {frame.shape}")
    if identity:
        out = frame.astype(np.float32) / np.float32(255.0)
    elif field is not None:
        out = lut_inverse(
            model.inv_lut, model.inv_lo, model.inv_hi, adaptive_light(model, frame, eye, field)
        )
    else:
        cw = white_response(model, frame)
        t = np.float32(alpha) * cw + np.float32(beta)
        y = target_to_projector(model, t.astype(np.float32), eye)
        if model.method == "pixel":
            y = np.clip(y, 0.0, 1.0)
        out = lut_inverse(model.inv_lut, model.inv_lo, model.inv_hi, y)
    return np.rint(np.clip(out, 0.0, 1.0) * np.float32(255.0)).astype(np.uint8)


def adaptive_light(
    model: RuntimeModel, frame: np.ndarray, eye: View, field: ToneField
) -> np.ndarray:
    """The adaptive tone map's projector light (H, W, 3) float32 in [0, 1] for an 8-bit
    frame at the model's grid (pixel method, one eye): the field's gain and offset at each
    pixel, the hue-keeping soft clip into the pixel's reach (:func:`soft_light`)."""
    if model.method != "pixel" or isinstance(eye, Audience):
        raise ValueError("the adaptive tone map needs the pixel method and one eye")
    cw = white_response(model, frame)
    m, a = screen_at(model, eye)
    u, v, c = tone_terms(np.linalg.inv(m).astype(np.float32), cw, a)
    lo, hi = grey_range(v, c)
    g, o = field_at(field, model.shape)
    return soft_light(u, v, c, (cw @ LUMA).astype(np.float32), g, o, lo, hi, field.hue)
