"""`viewcomp export-mpv`: the compensation as an mpv user shader, for kiosks that run mpv.

One text file that mpv loads with ``--glsl-shaders=FILE``: a ``//!HOOK OUTPUT`` pass (the
final image at the window's size, before mpv's colour management) that evaluates the
formula of docs/RUNTIME.md per output pixel, and ``//!TEXTURE`` sections with everything
it reads embedded as hexadecimal:

- ``VC_MAP0`` .. ``VC_MAP7`` (pixel method): the 32 per-pixel values of the packed layout
  (:data:`viewcomp.rt.gl.compensator.PACKED_LAYOUT`: Ww, Aw, Wc, Ac, refl, pos, the camera's
  lobe, zero), 4 per texel, ``rgba16`` (16-bit unsigned normalised: value = offset +
  t (max - min): the GL compensator's packed scheme at 16 instead of 20 bits) or, with
  ``precision=32``, ``rgba32f`` (exact, twice the size);
- ``VC_LUT`` (``rgba32f``, 2 rows): row 0 the forward LUT at the 256 levels, row 1 the
  inverse LUT (N entries on [inv_lo, inv_hi]).

The viewing angle is fixed at export (eye and tone map baked in), which every mpv with
user shaders runs (``vo=gpu`` and ``vo=gpu-next``); or, with ``param=True`` (pixel method
only), a ``//!PARAM angle`` (``TYPE float``, a uniform) that ``--glsl-shader-opts=angle=60``
sets, also while playing; the tone map then comes from a table over angles baked at export.
``//!PARAM`` needs mpv's ``vo=gpu-next`` with a libplacebo that parses it (newer than
v5.229; see docs/PLAYER.md for what was checked); older ones, and ``vo=gpu`` before mpv
added a subset of PARAM to it, refuse the whole file.

The tone map (alpha, beta) cannot follow the content inside mpv: it is chosen at export from
a sample (``tone_from``, e.g. a typical frame: the same choice ``viewcomp render`` makes for
that image), or by default from :func:`full_range_sample`, a conservative map that keeps
every colour of any content reachable.

Sampling: the maps are read with NEAREST filtering at ``HOOKED_pos``; when mpv's output is
the grid's size (fullscreen on the projector whose grid was calibrated) every output pixel
reads exactly its own texel. Input levels are ``255 * HOOKED`` (fractional for video after
mpv's yuv -> RGB; the forward LUT interpolates linearly, as the reference does).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from viewcomp.calib.comp.compensation import Compensation, thumbnail
from viewcomp.calib.comp.tonemap import DEFAULT_LAMBDA
from viewcomp.calib.model.reference import RuntimeModel
from viewcomp.rt.gl.compensator import PACKED_LAYOUT, camera_lobe

if TYPE_CHECKING:
    from viewcomp.calib.fit.calibrate import Calibration

TONE_TABLE_STEP = 5.0  # degrees between the baked tone maps of the PARAM variant
TONE_TABLE = np.arange(5.0, 175.0 + 1e-9, TONE_TABLE_STEP)


class ExportError(ValueError):
    """An mpv shader cannot be made with these settings; the message says why and the fix."""


@dataclass(frozen=True)
class MpvShaderInfo:
    """What an exported shader holds (for the CLI's summary and for tests)."""

    method: str
    grid: tuple[int, int]
    angle: float | None
    eye: tuple[float, float, float] | None
    param: bool
    alpha: float
    beta: float
    precision: int
    bytes: int


def _f(x: float) -> str:
    """A GLSL float literal that is exact for float32 (always with a decimal point)."""
    return f"{float(np.float32(x)):.9e}"


def _vec(v: Sequence[float]) -> str:
    return f"vec{len(v)}(" + ", ".join(_f(x) for x in v) + ")"


def full_range_sample(shape: tuple[int, int] = (24, 48)) -> np.ndarray:
    """A thumbnail (h, w, 3) uint8 where every neighbourhood holds black, white, the
    primaries, the secondaries and mid grey: a tone map chosen on it keeps all of them
    reachable everywhere on the screen (conservative: dimmer than one chosen on content).
    """
    h, w = shape
    colours = np.array(
        [[0, 0, 0], [255, 255, 255], [255, 0, 0], [0, 255, 0], [0, 0, 255],
         [0, 255, 255], [255, 0, 255], [255, 255, 0], [128, 128, 128]], np.uint8,
    )  # fmt: skip
    yy, xx = np.mgrid[0:h, 0:w]
    return colours[(xx + 3 * yy) % len(colours)]


def _field(model: RuntimeModel, lobe: np.ndarray, name: str, i: int | None, j: int | None):
    if name == "lobe":
        return lobe
    if name == "zero":
        return np.zeros(model.shape, np.float32)
    arr = getattr(model, name)
    return arr[..., i, j] if j is not None else arr[..., i]


def pack_maps(
    model: RuntimeModel, precision: int = 16
) -> tuple[list[np.ndarray], np.ndarray, np.ndarray]:
    """The pixel method's 32 values per pixel as 8 (H, W, 4) images (PACKED_LAYOUT order).

    ``precision`` 16: uint16 images and per-value (scale, offset), value = offset + t scale
    with t = q / 65535 the normalised texel (scale = max - min over the grid); 32: float32
    images with scale 1 and offset 0. Returns (images, scale (8, 4), offset (8, 4)).
    """
    if precision not in (16, 32):
        raise ExportError(f"precision is 16 or 32 bits, got {precision}")
    lobe = camera_lobe(model.refl, model.pos, np.asarray(model.cam_eye, np.float32), model.gamma)
    h, w = model.shape
    dtype = np.uint16 if precision == 16 else np.float32
    images = [np.empty((h, w, 4), dtype) for _ in range(8)]
    scale = np.ones(32, np.float64)
    offset = np.zeros(32, np.float64)
    for k, (name, i, j) in enumerate(PACKED_LAYOUT):
        f = np.asarray(_field(model, lobe, name, i, j), np.float64)
        if not np.all(np.isfinite(f)):
            raise ExportError(f"the calibration's {name} holds NaN or infinite values")
        img, c = images[k // 4], k % 4
        if precision == 32:
            img[..., c] = f
            continue
        lo, hi = float(f.min()), float(f.max())
        span = hi - lo
        scale[k], offset[k] = span, lo
        img[..., c] = 0 if span <= 0 else np.clip(np.rint((f - lo) / span * 65535.0), 0, 65535)
    return images, scale.reshape(8, 4), offset.reshape(8, 4)


def _lut_image(model: RuntimeModel) -> np.ndarray:
    """(2, Wl, 4) float32: row 0 the forward LUT (256 levels), row 1 the inverse LUT."""
    fwd = np.asarray(model.fwd_lut, np.float32)
    inv = np.asarray(model.inv_lut, np.float32)
    wl = max(256, inv.shape[0])
    img = np.zeros((2, wl, 4), np.float32)
    img[0, :256, :3] = fwd
    img[1, : inv.shape[0], :3] = inv
    img[..., 3] = 1.0
    return img


def _texture(name: str, image: np.ndarray, fmt: str) -> str:
    h, w = image.shape[:2]
    data = np.ascontiguousarray(image.astype("<u2" if fmt == "rgba16" else "<f4")).tobytes()
    return f"//!TEXTURE {name}\n//!SIZE {w} {h}\n//!FORMAT {fmt}\n//!FILTER NEAREST\n{data.hex()}\n"


_LUT_GLSL = """
vec3 vc_lut_row(float v, vec3 i) {
    return vec3(texture(VC_LUT, vec2((i.r + 0.5) / VC_LUT_W, v)).r,
                texture(VC_LUT, vec2((i.g + 0.5) / VC_LUT_W, v)).g,
                texture(VC_LUT, vec2((i.b + 0.5) / VC_LUT_W, v)).b);
}

// Forward LUT at fractional levels 0..255 (linear interpolation, as the reference).
vec3 vc_fwd(vec3 level) {
    vec3 t = clamp(level, 0.0, 255.0);
    vec3 i0 = min(floor(t), vec3(254.0));
    vec3 a = vc_lut_row(0.25, i0);
    vec3 b = vc_lut_row(0.25, i0 + 1.0);
    return a + (b - a) * (t - i0);
}

// Inverse LUT on [VC_INV_LO, VC_INV_HI] -> 0..1, sampled uniformly in the square root of
// the normalised value (docs/RUNTIME.md); linear interpolation.
vec3 vc_inv(vec3 y) {
    vec3 span = max(VC_INV_HI - VC_INV_LO, vec3(1e-12));
    vec3 t = sqrt(clamp((y - VC_INV_LO) / span, 0.0, 1.0)) * (VC_N_INV - 1.0);
    vec3 i0 = min(floor(t), vec3(VC_N_INV - 2.0));
    vec3 a = vc_lut_row(0.75, i0);
    vec3 b = vc_lut_row(0.75, i0 + 1.0);
    return a + (b - a) * (t - i0);
}

vec4 vc_out(vec3 result, float a) {
    return vec4(floor(clamp(result, 0.0, 1.0) * 255.0 + 0.5) / 255.0, a);
}
"""

_PIXEL_HOOK = """
vec4 hook() {
    vec2 uv = HOOKED_pos;
    vec4 src = HOOKED_tex(uv);
    vec3 pw = vc_fwd(src.rgb * 255.0);
    vec4 v0 = texture(VC_MAP0, uv) * VC_S[0] + VC_O[0];
    vec4 v1 = texture(VC_MAP1, uv) * VC_S[1] + VC_O[1];
    vec4 v2 = texture(VC_MAP2, uv) * VC_S[2] + VC_O[2];
    vec4 v3 = texture(VC_MAP3, uv) * VC_S[3] + VC_O[3];
    vec4 v4 = texture(VC_MAP4, uv) * VC_S[4] + VC_O[4];
    vec4 v5 = texture(VC_MAP5, uv) * VC_S[5] + VC_O[5];
    vec4 v6 = texture(VC_MAP6, uv) * VC_S[6] + VC_O[6];
    vec4 v7 = texture(VC_MAP7, uv) * VC_S[7] + VC_O[7];
    vec4 w0 = vec4(v0.xyz, v2.y);
    vec4 w1 = vec4(v0.w, v1.xy, v2.z);
    vec4 w2 = vec4(v1.zw, v2.x, v2.w);
    vec4 c0 = vec4(v3.xyz, v5.y);
    vec4 c1 = vec4(v3.w, v4.xy, v5.z);
    vec4 c2 = vec4(v4.zw, v5.x, v5.w);
    vec3 refl = v6.xyz;
    vec3 pos = vec3(v6.w, v7.xy);
    float cam_lobe = v7.z;

    vec3 eye = vc_eye();
    vec2 tone = vc_tone();
    vec3 cw = vec3(dot(w0.xyz, pw), dot(w1.xyz, pw), dot(w2.xyz, pw)) + vec3(w0.w, w1.w, w2.w);
    vec3 target = tone.x * cw + tone.y;
    float lobe_eye = pow(max(dot(refl, normalize(eye - pos)), 0.0), VC_GAMMA);
    vec3 ds = VC_KAPPA * (lobe_eye - cam_lobe);
    vec3 r0 = c0.xyz + ds.x * w0.xyz;
    vec3 r1 = c1.xyz + ds.y * w1.xyz;
    vec3 r2 = c2.xyz + ds.z * w2.xyz;
    vec3 b = target - vec3(c0.w, c1.w, c2.w);
    vec3 k0 = cross(r1, r2);
    float det = dot(r0, k0);
    vec3 y = (k0 * b.x + cross(r2, r0) * b.y + cross(r0, r1) * b.z) / det;
    return vc_out(vc_inv(clamp(y, 0.0, 1.0)), src.a);
}
"""

_PAPER_HOOK = """
vec4 hook() {
    vec4 src = HOOKED_tex(HOOKED_pos);
    vec3 cw = VC_WW * vc_fwd(src.rgb * 255.0);
    vec3 target = VC_ALPHA * cw + VC_BETA;
    return vc_out(vc_inv(VC_WC_INV * target), src.a);
}
"""


def _mat3(m: np.ndarray) -> str:
    """A GLSL mat3 literal (column-major) of a numpy (3, 3) matrix."""
    return "mat3(" + ", ".join(_f(x) for x in np.asarray(m, np.float64).T.ravel()) + ")"


def _array(name: str, kind: str, values: Sequence[str]) -> str:
    return f"const {kind} {name}[{len(values)}] = {kind}[{len(values)}]({', '.join(values)});"


def export_mpv_shader(
    cal: Calibration,
    *,
    method: str = "pixel",
    angle: float | None = 90.0,
    eye: Sequence[float] | None = None,
    param: bool = False,
    lam: float = DEFAULT_LAMBDA,
    tone_sample: np.ndarray | None = None,
    tone: tuple[float, float] | None = None,
    precision: int = 16,
    source: str = "",
) -> tuple[str, MpvShaderInfo]:
    """The mpv user shader text for a calibration (see the module docstring).

    Args:
        cal: the calibration.
        method: ``"pixel"`` or ``"paper"`` (fixed angle only).
        angle: the viewing angle (degrees) baked in, or with ``param`` the PARAM's default.
        eye: an eye position (metres) instead of ``angle`` (not with ``param``).
        param: a ``//!PARAM angle`` instead of a fixed angle (pixel method; gpu-next).
        lam: the tone map's lambda.
        tone_sample: an RGB frame (h, w, 3) uint8 already fitted to the grid whose tone map
            to bake (as ``viewcomp render`` would choose for it); None: full_range_sample.
        tone: (alpha, beta) to bake instead (fixed angle only).
        precision: 16 (rgba16 maps) or 32 (rgba32f maps).
        source: a note for the header (e.g. the bundle's path).

    Raises:
        ExportError: an impossible combination, with the fix.
    """
    if method not in ("pixel", "paper"):
        raise ExportError(f"method must be 'pixel' or 'paper', got {method!r}")
    if param and method != "pixel":
        raise ExportError("the paper method's matrices and LUTs are computed on the CPU for each "
                          "eye, so they cannot follow a shader parameter; fix: export it for a "
                          "fixed --angle, or use --method pixel with --param")  # fmt: skip
    if param and eye is not None:
        raise ExportError("--param makes the angle a parameter; it cannot be combined with --eye")
    if param and tone is not None:
        raise ExportError(
            "--param bakes a tone map per angle; give --tone-from, not --alpha/--beta"
        )
    if angle is None and eye is None:
        raise ExportError("give a viewing angle or an eye position")
    try:
        e = cal.eye(angle=None if eye is not None else angle, eye=eye)
    except ValueError as exc:
        raise ExportError(str(exc)) from None
    h, w = cal.shape
    comp = Compensation(cal, method, lam)
    sample = full_range_sample() if tone_sample is None else thumbnail(tone_sample)
    p = comp(sample, e)
    alpha, beta = (p.alpha, p.beta) if tone is None else (float(tone[0]), float(tone[1]))
    model = p.model
    v = cal.rig.viewer
    where = (f"angle {angle:g} deg" if eye is None else
             "eye ({:.4f}, {:.4f}, {:.4f}) m".format(*e))  # fmt: skip
    if param:
        where = f"angle from the shader parameter angle (default {angle:g} deg)"
    n_inv = int(model.inv_lut.shape[0])
    lut = _lut_image(model)
    consts = [
        f"const float VC_LUT_W = {_f(lut.shape[1])};",
        f"const float VC_N_INV = {_f(n_inv)};",
        f"const vec3 VC_INV_LO = {_vec(model.inv_lo)};",
        f"const vec3 VC_INV_HI = {_vec(model.inv_hi)};",
    ]
    binds = ["HOOKED"]
    textures: list[str] = []
    if method == "pixel":
        images, scale, offset = pack_maps(model, precision)
        fmt = "rgba16" if precision == 16 else "rgba32f"
        for k, img in enumerate(images):
            binds.append(f"VC_MAP{k}")
            textures.append(_texture(f"VC_MAP{k}", img, fmt))
        consts += [
            _array("VC_S", "vec4", [_vec(r) for r in scale]),
            _array("VC_O", "vec4", [_vec(r) for r in offset]),
            f"const vec3 VC_KAPPA = {_vec(model.kappa)};",
            f"const float VC_GAMMA = {_f(model.gamma)};",
        ]
        if param:
            alphas, betas = [], []
            for a in TONE_TABLE:
                ea = cal.eye(angle=float(a))
                t = comp.tone_map(model, sample, ea)
                alphas.append(_f(t.alpha))
                betas.append(_f(t.beta))
            consts += [
                f"const float VC_DIST = {_f(v.distance)};",
                f"const float VC_HEIGHT = {_f(v.height or 0.0)};",
                f"const float VC_TONE_FIRST = {_f(TONE_TABLE[0])};",
                f"const float VC_TONE_STEP = {_f(TONE_TABLE_STEP)};",
                f"const int VC_TONE_N = {len(TONE_TABLE)};",
                _array("VC_TONE_ALPHA", "float", alphas),
                _array("VC_TONE_BETA", "float", betas),
                "vec3 vc_eye() {",
                "    float t = radians(clamp(angle, 1.0, 179.0));",
                "    return vec3(VC_DIST * cos(t), VC_HEIGHT, VC_DIST * sin(t));",
                "}",
                "vec2 vc_tone() {",
                "    float x = clamp((angle - VC_TONE_FIRST) / VC_TONE_STEP, 0.0, "
                "float(VC_TONE_N - 1));",
                "    int i = min(int(floor(x)), VC_TONE_N - 2);",
                "    float f = x - float(i);",
                "    return vec2(mix(VC_TONE_ALPHA[i], VC_TONE_ALPHA[i + 1], f),",
                "                mix(VC_TONE_BETA[i], VC_TONE_BETA[i + 1], f));",
                "}",
            ]
        else:
            consts += [
                f"vec3 vc_eye() {{ return {_vec(e)}; }}",
                f"vec2 vc_tone() {{ return vec2({_f(alpha)}, {_f(beta)}); }}",
            ]
        hook = _PIXEL_HOOK
    else:
        consts += [
            f"const mat3 VC_WW = {_mat3(model.Ww)};",
            f"const mat3 VC_WC_INV = {_mat3(model.Wc_inv)};",
            f"const float VC_ALPHA = {_f(alpha)};",
            f"const float VC_BETA = {_f(beta)};",
        ]
        hook = _PAPER_HOOK
    binds.append("VC_LUT")
    textures.append(_texture("VC_LUT", lut, "rgba32f"))
    header = [
        "// viewcomp: view-dependent compensation as an mpv user shader (`viewcomp export-mpv`).",
        f"// Calibration {source or '(in memory)'}: projector grid {w}x{h}, {method} method, "
        f"{where}.",
        f"// Tone map: alpha {alpha:.4f}, beta {beta:.5f}"
        + (" (per angle from a table)" if param else "")
        + ".",
        "// Use: mpv --glsl-shaders=THIS_FILE --dither-depth=no --fullscreen VIDEO, on the",
        f"// projector, ideally at {w}x{h} (the maps are sampled at each output pixel).",
    ]
    if param:
        header.append("// Needs vo=gpu-next with a libplacebo that supports PARAM; set the "
                      "angle with --glsl-shader-opts=angle=60.")  # fmt: skip
    parts = ["\n".join(header) + "\n\n"]
    if param:
        parts.append(
            "//!PARAM angle\n//!DESC viewing angle in degrees (90 = in front)\n"
            f"//!TYPE float\n//!MINIMUM 1.0\n//!MAXIMUM 179.0\n{float(angle or 90.0):.1f}"
            "\n\n"
        )
    parts.append("//!HOOK OUTPUT\n")
    parts += [f"//!BIND {b}\n" for b in binds]
    parts.append(f"//!DESC viewcomp compensation ({method}, {where})\n")
    parts.append("\n".join(consts) + "\n" + _LUT_GLSL + hook + "\n")
    parts += textures
    text = "".join(parts)
    eye_t = None if param else (float(e[0]), float(e[1]), float(e[2]))
    info = MpvShaderInfo(method, (w, h), None if eye is not None else angle, eye_t, param,
                         alpha, beta, precision, len(text))  # fmt: skip
    return text, info
