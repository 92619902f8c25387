"""`viewcomp export-mpv`: the compensation as an mpv user shader, for kiosks that run mpv.

One text file that mpv loads with ``--glsl-shaders=FILE``: a ``//!HOOK OUTPUT`` pass (the
final image at the window's size, before mpv's colour management) that evaluates the
formula of docs/RUNTIME.md per output pixel, and ``//!TEXTURE`` sections with everything
it reads embedded as hexadecimal:

- ``VC_ROW0`` .. ``VC_ROW2`` (pixel method, a fixed eye): per pixel the affine map from the
  frame's forward-LUT value to the inverse LUT's position, the eye and the tone map folded
  in (:func:`held_rows`: the GL compensator's view cache), 12 numbers per pixel;
- ``VC_MAP0`` .. ``VC_MAP7`` (pixel method, ``param``: the eye follows the angle): texel k
  of every pixel of the GL compensator's maps
  (:func:`viewcomp.calib.model.shader_inputs.pixel_texels`: rows of Ww | Aw, rows of Wc | Ac,
  refl | the camera's lobe (R), p.xy | the camera's lobe (G, B)), 32 numbers per pixel;
- both ``rgba16`` (16-bit unsigned normalised: value = offset + t (max - min) per texel
  channel over the grid) or, with ``precision=32``, ``rgba32f`` (exact, twice the size);
- ``VC_LUT`` (``rgba32f``, 3 rows): row 0 the forward LUT at the 256 levels, row 1 the
  inverse LUT (N entries on [inv_lo, inv_hi]), row 2 the specular lobe's table (pixel
  method; zeros for the paper's).

The hook's GLSL is not written here: it is ``mpv_held.glsl``, ``mpv_pixel.glsl`` (PARAM)
or ``mpv_paper.glsl`` of
:mod:`viewcomp.shaders` with the formula of ``compensate_core.glsl`` (the GL compensator's)
expanded into it, after
``#define`` lines with this export's numbers (the same CPU folding as the GL compensator:
:func:`~viewcomp.calib.model.shader_inputs.inverse_position`,
:func:`~viewcomp.calib.model.shader_inputs.paper_rows`).

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

Registration: ``viewcomp render`` and ``play`` fit every frame to the grid (scaled, aspect
kept, centred on black: :func:`viewcomp.rt.media.frames.fit_rect`) and compensate the bars
too. mpv's OUTPUT hook sees only mpv's video rectangle, so the documented command line
(:func:`mpv_args`) makes mpv do that same fit itself, before the hook:
:func:`fit_filter`, libavfilter's ``scale`` (bilinear, left-sited chroma: the same swscale
call as :class:`viewcomp.rt.media.video.VideoReader`'s) and ``pad`` to the grid's size.
The video then has the grid's aspect, the hook covers the whole window (black bars
included, compensated as ``render`` does) and the maps are read with NEAREST filtering at
``HOOKED_pos``: at the grid's size each output pixel reads exactly its own texel. Without
the filter the hook still reads the maps where the picture lies in the grid (``mpv_lut.glsl``'s
``vc_map_pos``), but mpv's own bars stay uncompensated. Input levels are ``255 * HOOKED``
(fractional for video after mpv's yuv -> RGB; the forward LUT interpolates linearly, as the
reference does).
"""

from __future__ import annotations

import importlib.resources
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from viewcomp.calib.comp.compensation import Compensation, thumbnail
from viewcomp.calib.comp.tonemap import DEFAULT_LAMBDA
from viewcomp.calib.errors import ExportError
from viewcomp.calib.model.gamut import ToneField
from viewcomp.calib.model.reference import (
    View,
    audience_normal,
    compensate,
    screen_at,
    tone_terms,
)
from viewcomp.calib.model.runtime import RuntimeModel
from viewcomp.calib.model.shader_inputs import inverse_position, paper_rows
from viewcomp.calib.world import eye as eye_limits
from viewcomp.calib.world.audience import Audience
from viewcomp.rt.export.mpv_adaptive import adaptive_defines, adaptive_texels
from viewcomp.rt.export.mpv_pack import pack_images, pack_maps, split_smooth
from viewcomp.rt.export.mpv_verify import block_means, check_line, check_still, texture_line
from viewcomp.shaders import array_literal, assemble, literal, vec_literal

if TYPE_CHECKING:
    from viewcomp.calib.fit.calibrate import Calibration

TONE_TABLE_STEP = 5.0  # degrees between the baked tone maps of the PARAM variant
TONE_TABLE = np.arange(5.0, 175.0 + 1e-9, TONE_TABLE_STEP)


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
    tone: str = "global"  # how the tone map was chosen: paper, global or adaptive


def fit_filter(grid: tuple[int, int]) -> str:
    """mpv's ``--vf`` value that fits any video to a (W, H) grid exactly as ``viewcomp
    render``/``play`` do: scaled with aspect kept to even sizes (bilinear, chroma sited left
    as MPEG-2/H.264 put it, which is what PyAV's reformat assumes), centred on black, square
    pixels. The same libswscale call as :class:`viewcomp.rt.media.video.VideoReader`, so the
    planes are identical (checked against Debian 12's FFmpeg 5.1 in tests/rt/export/test_mpv.py)."""
    w, h = grid
    return (
        f"lavfi=[scale={w}:{h}:force_original_aspect_ratio=decrease:force_divisible_by=2"
        ":flags=bilinear:in_h_chr_pos=0:out_h_chr_pos=0"
        f",pad={w}:{h}:(ow-iw)/2:(oh-ih)/2:black,setsar=1]"
    )


def mpv_args(shader: str, grid: tuple[int, int], guard: str | None = None) -> list[str]:
    """mpv's options for an exported shader (besides the screen and the files): the shader,
    no dithering (the shader outputs exact levels), :func:`fit_filter` and, given its path,
    the guard script (:func:`guard_script`)."""
    args = [f"--glsl-shaders={shader}", "--dither-depth=no", f"--vf={fit_filter(grid)}"]
    return args + ([f"--script={guard}"] if guard else [])


def guard_script() -> str:
    """The text of ``mpv_guard.lua`` (package data of :mod:`viewcomp.shaders`): an mpv script
    that quits mpv with exit status 2 when the shader is missing or mpv's video output logs
    an error (a shader it rejected), instead of playing uncompensated video."""
    res = importlib.resources.files("viewcomp.shaders").joinpath("mpv_guard.lua")
    return res.read_text(encoding="utf-8")


def full_range_sample(shape: tuple[int, int] = (24, 48)) -> np.ndarray:
    """A thumbnail (h, w, 3) uint8 where every neighbourhood holds black, white, the
    primaries, the secondaries and mid grey: a tone map chosen on it keeps all of them
    reachable everywhere on the screen (conservative: dimmer than one chosen on content).
    """
    h, w = shape
    colours = np.array(
        [
            [0, 0, 0],
            [255, 255, 255],
            [255, 0, 0],
            [0, 255, 0],
            [0, 0, 255],
            [0, 255, 255],
            [255, 0, 255],
            [255, 255, 0],
            [128, 128, 128],
        ],
        np.uint8,
    )
    yy, xx = np.mgrid[0:h, 0:w]
    return colours[(xx + 3 * yy) % len(colours)]


def held_rows(
    model: RuntimeModel, eye: View, alpha: float, beta: float, sq: dict[str, np.ndarray]
) -> np.ndarray:
    """The pixel method for one eye (or an audience) and tone map as one affine map per
    pixel, (H, W, 3, 4) float64: row i = (G_i | w_i) with t2_i = G_i . pw + w_i the inverse
    LUT's squared position (``pixel_t2``'s, before its clamp) of the frame's forward-LUT
    value pw.

    The GL compensator's view cache (docs/RUNTIME.md) with the tone map folded in:
    y = M^-1 (alpha (Ww pw + Aw) + beta 1 - A) = alpha M^-1 Ww pw + alpha u + beta v + c,
    M and A from :func:`~viewcomp.calib.model.reference.screen_at`, (u, v, c) from
    :func:`~viewcomp.calib.model.reference.tone_terms`, solved in float64 on the CPU; for an
    :class:`~viewcomp.calib.world.audience.Audience` of several viewers M^-1 is N^-1 S and
    M^-1 A is N^-1 q (:func:`~viewcomp.calib.model.reference.audience_normal`); then
    t2 = scale y - off (``sq``: :func:`~viewcomp.calib.model.shader_inputs.inverse_position`).
    12 numbers per pixel instead of the 32 of the maps.
    """
    if isinstance(eye, Audience) and len(eye) > 1:
        n, s_t, q = (a.astype(np.float64) for a in audience_normal(model, eye))
        n_inv = np.linalg.inv(n)
        m_inv = n_inv @ s_t
        d = np.einsum("hwij,hwj->hwi", n_inv, q)
        assert model.Aw is not None  # a pixel model always has it
        u, v, _ = tone_terms(m_inv, model.Aw.astype(np.float64), np.zeros_like(d))
        c = -d
    else:
        one = eye.eyes[0] if isinstance(eye, Audience) else eye
        m, amb = screen_at(model, np.asarray(one, np.float32))
        m_inv = np.linalg.inv(m.astype(np.float64))
        assert model.Aw is not None  # a pixel model always has it
        u, v, c = tone_terms(m_inv, model.Aw.astype(np.float64), amb.astype(np.float64))
    g = np.einsum("hwij,hwjk->hwik", m_inv, model.Ww.astype(np.float64))
    rows = np.concatenate([alpha * g, (alpha * u + beta * v + c)[..., None]], axis=-1)
    rows *= np.asarray(sq["scale"], np.float64)[:, None]
    rows[..., 3] -= np.asarray(sq["off"], np.float64)
    return rows


def _lut_image(model: RuntimeModel) -> np.ndarray:
    """(3, Wl, 4) float32: row 0 the forward LUT (256 levels), row 1 the inverse LUT, row 2
    the lobe table (zeros for the paper's method)."""
    fwd = np.asarray(model.fwd_lut, np.float32)
    inv = np.asarray(model.inv_lut, np.float32)
    lobe = np.asarray(model.lobe, np.float32) if model.method == "pixel" else np.zeros((2, 3))
    wl = max(256, inv.shape[0], lobe.shape[0])
    img = np.zeros((3, wl, 4), np.float32)
    img[0, :256, :3] = fwd
    img[1, : inv.shape[0], :3] = inv
    img[2, : lobe.shape[0], :3] = lobe
    img[..., 3] = 1.0
    return img


def _texture(name: str, image: np.ndarray, fmt: str) -> str:
    h, w = image.shape[:2]
    dtype = {"rgba8": "u1", "rgba16": "<u2", "rgba32f": "<f4"}[fmt]
    data = np.ascontiguousarray(image.astype(dtype)).tobytes()
    return f"//!TEXTURE {name}\n//!SIZE {w} {h}\n//!FORMAT {fmt}\n//!FILTER NEAREST\n{data.hex()}\n"


def export_mpv_shader(
    cal: Calibration,
    *,
    method: str = "pixel",
    angle: float | None = 90.0,
    eye: Sequence[float] | None = None,
    audience: Audience | None = None,
    param: bool = False,
    lam: float = DEFAULT_LAMBDA,
    tone_sample: np.ndarray | None = None,
    tone: tuple[float, float] | None = None,
    precision: int = 16,
    source: str = "",
    tone_mode: str | None = None,
) -> tuple[str, MpvShaderInfo]:
    """The mpv user shader text for a calibration (see the module docstring).

    Args:
        cal: the calibration.
        method: ``"pixel"`` or ``"paper"`` (fixed angle only).
        angle: the viewing angle (degrees) baked in, or with ``param`` the PARAM's default.
        eye: an eye position (metres) instead of ``angle`` (not with ``param``).
        audience: several viewers instead of ``angle`` (pixel method, not with ``param``:
            the least squares for all of them, docs/MODEL.md section 6).
        param: a ``//!PARAM angle`` instead of a fixed angle (pixel method; gpu-next).
        lam: the tone map's lambda.
        tone_sample: an RGB frame (h, w, 3) uint8 already fitted to the grid whose tone map
            to bake (as ``viewcomp render`` would choose for it); None: full_range_sample.
        tone: (alpha, beta) to bake instead (fixed angle only).
        precision: 16 (rgba16 maps), 32 (rgba32f maps) or 8 (fixed-eye pixel method: a
            smooth base at 1/4 of the grid in rgba32f plus the residual in rgba8 maps,
            :func:`split_smooth`; about half the size of 16).
        source: a note for the header (e.g. the bundle's path).
        tone_mode: how the tone map is chosen (``Compensation``'s ``tone``): ``"paper"``,
            ``"global"`` or ``"adaptive"`` (the smooth field with the hue-keeping soft clip,
            one per export, chosen for ``tone_sample``; pixel method, a fixed eye, precision
            16 or 32: :mod:`~viewcomp.rt.export.mpv_adaptive`); None: the method's.

    Raises:
        ExportError: an impossible combination, with the fix.
    """
    req = _Request(
        method,
        angle,
        None if eye is None else tuple(float(v) for v in eye),
        audience,
        param,
        lam,
        tone_sample,
        tone,
        precision,
        source,
        tone_mode,
    )
    req, e = _check(cal, req)
    build = _build(cal, req, e)
    return _assemble(req, build)


@dataclass(frozen=True)
class _Request:
    """:func:`export_mpv_shader`'s arguments, checked by :func:`_check`."""

    method: str
    angle: float | None
    eye: tuple[float, ...] | None
    audience: Audience | None
    param: bool
    lam: float
    tone_sample: np.ndarray | None
    tone: tuple[float, float] | None
    precision: int
    source: str
    tone_mode: str | None = None


@dataclass
class _Build:
    """What :func:`_build` computed: the tone map, the ``#define`` values, the bound textures
    and their ``//!TEXTURE`` sections, the grid and the eye (metres)."""

    alpha: float
    beta: float
    grid: tuple[int, int]
    eye: np.ndarray
    defines: dict[str, str | int | float] = field(default_factory=dict)
    binds: list[str] = field(default_factory=lambda: ["HOOKED"])
    textures: list[str] = field(default_factory=list)
    check: str = ""
    check_tone: tuple[float, float] | None = None  # --param: the table's at the default angle
    field: ToneField | None = None  # the adaptive tone map baked in


def _check(cal: Calibration, req: _Request) -> tuple[_Request, np.ndarray]:
    """Refuse an impossible combination (ExportError, with the fix) before any work; returns
    the request (one viewer of an audience becomes an eye) and the eye (3,) metres (an
    audience's weighted mean)."""
    if req.method not in ("pixel", "paper"):
        raise ExportError(f"method must be 'pixel' or 'paper', got {req.method!r}")
    if req.param and req.method != "pixel":
        raise ExportError(
            "the paper method's matrices and LUTs are computed on the CPU for each "
            "eye, so they cannot follow a shader parameter; fix: export it for a "
            "fixed --angle, or use --method pixel with --param"
        )
    if req.param and req.eye is not None:
        raise ExportError("--param makes the angle a parameter; it cannot be combined with --eye")
    if req.param and req.tone is not None:
        raise ExportError(
            "--param bakes a tone map per angle; give --tone-from, not --alpha/--beta"
        )
    if req.audience is not None and len(req.audience) == 1:
        req = replace(req, eye=tuple(float(v) for v in req.audience.eyes[0]), audience=None)
    if req.audience is not None and (req.param or req.method != "pixel"):
        raise ExportError(
            "an audience of several viewers is baked in for the pixel method; fix: "
            "drop --param, use --method pixel"
        )
    if req.angle is None and req.eye is None and req.audience is None:
        raise ExportError("give a viewing angle or an eye position")
    if req.precision == 8 and (req.param or req.method != "pixel"):
        raise ExportError(
            "--precision 8 stores the fixed-eye pixel method's rows; fix: use "
            "16 with --param or --method paper"
        )
    _check_tone(req)
    if req.audience is not None:
        return req, req.audience.centre
    e = cal.eye(angle=None if req.eye is not None else req.angle, eye=req.eye, error=ExportError)
    return req, e


def _check_tone(req: _Request) -> None:
    """Refuse a tone choice the export cannot bake (ExportError, with the fix)."""
    if req.tone_mode not in (None, "paper", "global", "adaptive"):
        raise ExportError(f"tone must be paper, global or adaptive, got {req.tone_mode!r}")
    if req.tone_mode in ("global", "adaptive") and req.method != "pixel":
        raise ExportError(f"--tone {req.tone_mode} needs --method pixel (the paper's: paper)")
    if req.tone_mode != "adaptive":
        return
    for bad, fix in (
        (req.param, "drop --param (the field is chosen for one eye)"),
        (req.audience is not None, "drop --audience (the field is for one eye)"),
        (req.tone is not None, "give --tone-from, not --alpha/--beta"),
        (req.precision == 8, "use --precision 16 or 32"),
    ):
        if bad:
            raise ExportError(f"--tone adaptive is baked for one fixed eye; fix: {fix}")


def _build(cal: Calibration, req: _Request, e: np.ndarray) -> _Build:
    """The tone map and everything the hook reads: ``#define`` values and textures."""
    h, w = cal.shape
    comp = Compensation(cal, req.method, req.lam, tone=req.tone_mode)
    sample = full_range_sample() if req.tone_sample is None else thumbnail(req.tone_sample)
    view: View = req.audience if req.audience is not None else e
    p = comp(sample, view)
    alpha, beta = (
        (p.alpha, p.beta) if req.tone is None else (float(req.tone[0]), float(req.tone[1]))
    )
    model = p.model
    n_inv = int(model.inv_lut.shape[0])
    lut = _lut_image(model)
    out = _Build(alpha, beta, (w, h), e, field=p.field)
    out.defines.update({
        "VC_GRID": vec_literal((w, h)), "VC_LUT_W": literal(lut.shape[1]), "VC_N_INV": n_inv,
    })  # fmt: skip
    if req.method == "pixel":
        _build_pixel(cal, req, out, comp, model, sample, view)
    else:
        assert model.Wc_inv is not None  # a paper model always has it
        rows = paper_rows(model.Ww, model.Wc_inv, model.inv_lo, model.inv_hi, n_inv, alpha, beta)
        out.defines.update({f"VC_A{i}": vec_literal(rows[i]) for i in range(3)})
    out.binds.append("VC_LUT")
    out.textures.append(_texture("VC_LUT", lut, "rgba32f"))
    # The check value (mpv_verify): what the hook must output for the check's still, from
    # the numpy reference at this eye and tone map (with --param: the default angle's).
    a_c, b_c = out.check_tone or (alpha, beta)
    still = check_still((w, h))
    seen = compensate(model, still, view, a_c, b_c, field=out.field)
    out.check = check_line(block_means(seen), (w, h))
    return out


def _build_pixel(
    cal: Calibration,
    req: _Request,
    out: _Build,
    comp: Compensation,
    model: RuntimeModel,
    sample: np.ndarray,
    view: View,
) -> None:
    """The pixel method's maps (``param``: the eye follows the angle) or its view cache for
    a fixed eye, with their ``#define`` values, into ``out``."""
    sq = inverse_position(model.inv_lo, model.inv_hi, int(model.inv_lut.shape[0]))
    d = out.defines
    d.update({f"VC_SQ_{key.upper()}": vec_literal(val) for key, val in sq.items()})
    if req.param:
        images, scale, offset = pack_maps(model, req.precision)
        name = "VC_MAP"
    elif out.field is not None:
        try:
            texels = adaptive_texels(model, np.asarray(view))
        except np.linalg.LinAlgError:
            msg = "the screen's mixing matrix is singular at this eye"
            raise ExportError(f"{msg}; fix: recalibrate, or use another --angle") from None
        d.update(adaptive_defines(out.field, out.grid))
        images, scale, offset = pack_images(texels, req.precision)
        name = "VC_ROW"
    else:
        try:
            rows = held_rows(model, view, out.alpha, out.beta, sq)
        except np.linalg.LinAlgError:
            msg = "the screen's mixing matrix is singular at this eye"
            raise ExportError(f"{msg}; fix: recalibrate, or use another --angle") from None
        if req.precision == 8:
            base, rows = split_smooth(rows)
            h_b, w_b = base.shape[:2]
            for k in range(3):
                out.binds.append(f"VC_BASE{k}")
                out.textures.append(_texture(f"VC_BASE{k}", base[:, :, k], "rgba32f"))
            d["VC_BASE_SIZE"] = vec_literal((w_b, h_b))
        d["VC_SPLIT"] = int(req.precision == 8)
        images, scale, offset = pack_images(rows, req.precision)
        name = "VC_ROW"
    fmt = {8: "rgba8", 16: "rgba16"}.get(req.precision, "rgba32f")
    for k, img in enumerate(images):
        out.binds.append(f"{name}{k}")
        out.textures.append(_texture(f"{name}{k}", img, fmt))
    d.update({
        "VC_S_INIT": array_literal("vec4", [vec_literal(r) for r in scale]),
        "VC_O_INIT": array_literal("vec4", [vec_literal(r) for r in offset]),
    })  # fmt: skip
    if req.param:
        alphas, betas = [], []
        tones = np.zeros((len(TONE_TABLE), 2))
        for k, a in enumerate(TONE_TABLE):
            t = comp.tone_map(model, sample, cal.eye(angle=float(a)))
            alphas.append(literal(t.alpha))
            betas.append(literal(t.beta))
            tones[k] = t.alpha, t.beta
        # the hook interpolates the table linearly (mpv_pixel.glsl); so does the check value
        at = float(req.angle if req.angle is not None else 90.0)
        out.check_tone = (
            float(np.interp(at, TONE_TABLE, tones[:, 0])),
            float(np.interp(at, TONE_TABLE, tones[:, 1])),
        )
        v = cal.rig.viewer
        d.update({
            "VC_LOBE_HALF": "true" if model.lobe_half else "false",
            "VC_LOBE_N": int(np.shape(model.lobe)[0]),
            "VC_LOBE_BLACK": vec_literal(model.lobe_black),
            "VC_DIST": literal(v.distance),
            "VC_HEIGHT": literal(v.height or 0.0),
            "VC_TONE_FIRST": literal(TONE_TABLE[0]),
            "VC_TONE_STEP": literal(TONE_TABLE_STEP),
            "VC_TONE_N": len(TONE_TABLE),
            "VC_TONE_ALPHA_INIT": array_literal("float", alphas),
            "VC_TONE_BETA_INIT": array_literal("float", betas),
            **eye_limits.glsl_defines(),
        })  # fmt: skip


def _assemble(req: _Request, b: _Build) -> tuple[str, MpvShaderInfo]:
    """The shader's text: a header with the mpv command line, the PARAM, the hook's
    directives and GLSL, the textures; and its :class:`MpvShaderInfo`."""
    (w, h), e, method, angle = b.grid, b.eye, req.method, req.angle
    where = (
        f"angle {angle:g} deg" if req.eye is None else "eye ({:.4f}, {:.4f}, {:.4f}) m".format(*e)
    )
    if req.audience is not None:
        where = (
            f"an audience of {len(req.audience)} viewers around "
            + "({:.4f}, {:.4f}, {:.4f}) m".format(*e)
        )
    if req.param:
        where = f"angle from the shader parameter angle (default {angle:g} deg)"
    header = [
        "// viewcomp: view-dependent compensation as an mpv user shader (`viewcomp export-mpv`).",
        f"// Calibration {req.source or '(in memory)'}: projector grid {w}x{h}, {method} method, "
        f"{where}.",
        (
            f"// Tone map: adaptive, a {b.field.nodes[0]}x{b.field.nodes[1]}-node field."
            if b.field is not None
            else f"// Tone map: alpha {b.alpha:.4f}, beta {b.beta:.5f}"
            + (" (per angle from a table)" if req.param else "")
            + "."
        ),
        f"// Use, fullscreen on the projector (ideally at {w}x{h}):",
        "//   mpv " + " ".join(mpv_args("THIS_FILE", (w, h))) + " --fullscreen VIDEO",
        "// (the --vf fits the video to the grid as `viewcomp render` does, bars included).",
        "// `viewcomp check-mpv THIS_FILE` runs mpv on a test still and compares the output",
        "// with this value (mpv_verify; a plain comment, which mpv ignores):",
        b.check,
        texture_line(b.binds[1:]),
    ]
    if req.param:
        header.append(
            "// Needs vo=gpu-next with a libplacebo that supports PARAM; set the "
            "angle with --glsl-shader-opts=angle=60."
        )
    parts = ["\n".join(header) + "\n\n"]
    if req.param:  # the PARAM's range: the limits of viewcomp.calib.world.eye
        parts.append(
            "//!PARAM angle\n//!DESC viewing angle in degrees (90 = in front)\n"
            f"//!TYPE float\n//!MINIMUM {eye_limits.ANGLE_MIN:.1f}\n"
            f"//!MAXIMUM {eye_limits.ANGLE_MAX:.1f}\n{float(angle or 90.0):.1f}\n\n"
        )
    parts.append("//!HOOK OUTPUT\n")
    parts += [f"//!BIND {name}\n" for name in b.binds]
    parts.append(f"//!DESC viewcomp compensation ({method}, {where})\n")
    hook = "mpv_paper.glsl" if method == "paper" else ("mpv_pixel.glsl" if req.param else "")
    hook = hook or ("mpv_adaptive.glsl" if b.field is not None else "mpv_held.glsl")
    parts.append(assemble(hook, b.defines, directives=False).source)
    parts += b.textures
    text = "".join(parts)
    eye_t = None if req.param else (float(e[0]), float(e[1]), float(e[2]))
    shown_angle = None if req.eye is not None or req.audience is not None else angle
    tone = "adaptive" if b.field is not None else req.tone_mode
    info = MpvShaderInfo(
        method, (w, h), shown_angle, eye_t, req.param, b.alpha, b.beta, req.precision, len(text),
        tone=tone or ("global" if method == "pixel" else "paper"),
    )  # fmt: skip
    return text, info
