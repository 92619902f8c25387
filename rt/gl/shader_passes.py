"""The shader passes of the GL compensator: one compiled program per variant (method,
input, yuv coefficients) and the per-frame values each draw hands it.

What is fixed for a :class:`~viewcomp.rt.gl.compensator.Compensator` is compiled in as
``#define`` literals; what changes per frame is handed over as flat inputs
(:meth:`ShaderPasses._frame_values`), which cost less per draw on llvmpipe than a uniform
block (docs/BENCHMARKS.md).
"""

from __future__ import annotations

import itertools
from typing import TYPE_CHECKING, Any

import moderngl
import numpy as np

from viewcomp.calib.model.gamut import ToneField
from viewcomp.calib.model.runtime import RuntimeModel
from viewcomp.calib.model.shader_inputs import (
    MAP_TEXELS,
    field_columns,
    field_nodes,
    field_step,
    gamut_constants,
    paper_rows,
    pixel_texel_blocks,
)
from viewcomp.calib.world.audience import MAX_VIEWERS, Audience
from viewcomp.rt.gl.context import BufferTexture, ProcAddress, set_sampler_units
from viewcomp.rt.media.frames import yuv_coefficients
from viewcomp.shaders import build_program, literal, vec_literal

_METHODS = {"identity": 0, "pixel": 1, "paper": 2}
_CACHED, _BUILD_VIEW = 3, 4  # shader METHODs of the pixel method's view cache
_AUDIENCE, _BUILD_AUDIENCE = 5, 6  # an audience: solved per draw, its view cache
_ADAPTIVE, _ADAPTIVE_CACHED = 7, 8  # the adaptive tone map: solved per draw, from the cache
_VIEW_TEXELS = 5  # per pixel in the view cache: rows of G | a, b | n_lo, d | n_hi
_PATHS = {
    0: "identity", 1: "solve", 2: "paper", _CACHED: "cached", _AUDIENCE: "audience",
    _ADAPTIVE: "adaptive", _ADAPTIVE_CACHED: "adaptive-cached",
}  # fmt: skip
_SAMPLERS = "u_rgb u_y u_uv u_fwd u_inv u_maps u_view u_lobe u_luma u_fcol".split()


class ShaderPasses:
    """Programs and draws of :class:`~viewcomp.rt.gl.compensator.Compensator` (a mixin)."""

    ctx: moderngl.Context
    method: str
    width: int
    height: int
    eye: np.ndarray
    alpha: float
    beta: float
    audience: Audience | None
    field: ToneField | None
    _identity: bool
    _input: int
    _yuv_key: tuple[str, str]
    _consts: dict[str, str | int]
    _programs: dict[tuple[Any, ...], tuple[Any, Any]]
    _units: list[tuple[int, Any]]
    _loader: ProcAddress | None
    _Ww: np.ndarray
    _Wc_inv: np.ndarray
    _inv_lo: np.ndarray
    _inv_hi: np.ndarray
    _n_inv: int
    _fcol_key: tuple[bytes, bytes] | None = None  # the field u_fcol holds
    _fcol_bytes = 0

    if TYPE_CHECKING:  # the compensator's own, declared for the type checker

        def _track(self, obj: Any) -> Any: ...

        def _buffer_texture(self, data: np.ndarray | int, fmt: str) -> BufferTexture: ...

        def _shader_method(self) -> int: ...

    def _upload_pixel_maps(self, model: RuntimeModel) -> dict[str, Any]:
        """The maps as one buffer texture: texel k of pixel (x, y) at 8 (y W + x) + k,
        written a block of rows at a time (:func:`pixel_texel_blocks`)."""
        row_bytes = self.width * MAP_TEXELS * 16
        blocks = pixel_texel_blocks(model)  # checks the model before anything is made
        first = next(blocks)
        tex = self._buffer_texture(row_bytes * self.height, "rgba32f")
        for r0, block in itertools.chain([first], blocks):
            tex.write(block, offset=row_bytes * r0)
        return {"u_maps": tex}

    def _program(self, method: int) -> tuple[Any, Any]:
        """(program, vertex array) of shader ``method`` on the current input, compiled once."""
        inp = 0 if method in (_BUILD_VIEW, _BUILD_AUDIENCE) else self._input
        yuv = self._yuv_key if inp == 1 else None
        adaptive = method in (_ADAPTIVE, _ADAPTIVE_CACHED)
        nodes = self.field.nodes if adaptive and self.field is not None else None
        key = (method, inp, yuv, nodes)
        if key not in self._programs:
            defines: dict[str, str | int | float] = {**self._consts, "METHOD": method, "INPUT": inp}
            if nodes is not None:
                defines.update(self._field_defines(nodes))
            if yuv is not None:
                k = yuv_coefficients(*yuv)  # type: ignore[arg-type]
                defines["YUV_K"] = f"ivec4({k.cy}, {k.cr_r}, {k.cb_b}, {k.y_off})"
                defines["YUV_KG"] = f"ivec2({k.cb_g}, {k.cr_g})"
            prog = self._track(build_program(self.ctx, defines=defines))
            vao = self._track(self.ctx.vertex_array(prog, []))
            # Distinct units: sampler types differ (2D and buffer samplers).
            units = {n: i for i, n in enumerate(_SAMPLERS) if n in prog}
            set_sampler_units(prog, units, self._loader)
            self._programs[key] = (prog, vao)
        return self._programs[key]

    def set_field(self, field: ToneField | None) -> None:
        """The adaptive tone map (pixel method; :mod:`~viewcomp.calib.model.gamut`) in place
        of (alpha, beta) for one eye, or None for (alpha, beta) again. An audience of several
        viewers draws with (alpha, beta) (the field is for one eye). A field of other nodes
        than the last compiles its program once (~0.1-0.3 s)."""
        if field is not None:
            if self.method != "pixel":
                raise ValueError(f"the adaptive tone map needs the pixel method, not {self.method}")
            field_nodes(field)  # checks it
        self.field = field

    def _field_defines(self, nodes: tuple[int, int]) -> dict[str, str | int | float]:
        """The adaptive variants' compiled-in constants for a field of ``nodes`` = (ny, nx)."""
        g = gamut_constants()
        return {
            "FIELD_NY": nodes[0],
            "FIELD_NX": nodes[1],
            "FIELD_STEP": vec_literal(field_step(nodes, (self.height, self.width))),
            "GAMUT_K": vec_literal(g["k"]),
            "GAMUT_LIMIT": literal(float(g["limit"][0])),
            "GAMUT_LUMA": vec_literal(g["luma"]),
        }

    def _write_field_columns(self, field: ToneField) -> None:
        """The field's rows along x (:func:`field_columns`) into ``u_fcol`` when it changed
        (one buffer of 3 x W x 8 bytes, grown when a field has more rows)."""
        key = (field.gain.tobytes(), field.offset.tobytes())
        if self._fcol_key == key:
            return
        cols = field_columns(field, self.width)
        unit = _SAMPLERS.index("u_fcol")
        tex = self._units[unit][1]
        if tex is None or self._fcol_bytes < cols.nbytes:
            tex = self._buffer_texture(cols.nbytes, "rg32f")
            self._units[unit] = (unit, tex)
            self._fcol_bytes = cols.nbytes
        tex.write(cols)
        tex.use(unit)
        self._fcol_key = key

    def _frame_values(self) -> bytes:
        """The per-frame inputs v_frame[4] (vec4 each) of the current variant, as bytes."""
        out = np.zeros((4, 4), np.float32)
        if self._identity:
            pass
        elif self.method == "pixel":  # shader METHODs 1, 3 and 4 alike
            out[0, :3] = self.eye
            out[0, 3] = self.alpha
            out[1, 0] = self.beta
            out[1, 1] = self.field.hue if self.field is not None else 1.0
        elif self.method == "paper":
            out[:3] = paper_rows(
                self._Ww,
                self._Wc_inv,
                self._inv_lo,
                self._inv_hi,
                self._n_inv,
                self.alpha,
                self.beta,
            )
        return out.tobytes()

    def _audience_values(self) -> bytes:
        """The audience as the shader's u_eyes[MAX_VIEWERS]: (eye.xyz, weight) per viewer."""
        out = np.zeros((MAX_VIEWERS, 4), np.float32)
        if self.audience is not None:
            k = len(self.audience)
            out[:k, :3] = self.audience.eyes
            out[:k, 3] = self.audience.weights
        return out.tobytes()

    def _render(self, method: int, flip_y: int) -> None:
        prog, vao = self._program(method)
        if "u_frame" in prog:  # the linker may keep only the elements a variant reads
            u = prog["u_frame"]
            u.write(self._frame_values()[: 16 * max(1, u.array_length)])
        if "u_flip_y" in prog:
            prog["u_flip_y"].value = flip_y
        if "u_n_eyes" in prog:
            prog["u_n_eyes"].value = len(self.audience) if self.audience is not None else 0
        if "u_eyes" in prog:
            prog["u_eyes"].write(self._audience_values())
        if "u_fcol" in prog and self.field is not None:
            self._write_field_columns(self.field)
        for unit, tex in self._units:
            if tex is not None:
                tex.use(unit)
        vao.render(moderngl.TRIANGLES, vertices=3)

    def _draw(self, framebuffer: Any, viewport: tuple[int, int, int, int], flip_y: int) -> None:
        method = self._shader_method()  # may render the view cache first
        self.last_path = _PATHS[method]
        framebuffer.use()
        self.ctx.viewport = viewport
        self._render(method, flip_y)
