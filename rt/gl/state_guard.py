"""Saving and restoring a host's GL state around viewcomp's drawing (raw GL, any host), and
the few raw GL calls moderngl lacks (a scaling blit, a glFinish without the GIL)."""

from __future__ import annotations

import ctypes
from typing import TYPE_CHECKING, Any

from viewcomp.rt.gl.context import ProcAddress, gl_function

if TYPE_CHECKING:
    import moderngl

_GL_READ_FRAMEBUFFER = 0x8CA8
_GL_DRAW_FRAMEBUFFER = 0x8CA9
_GL_COLOR_BUFFER_BIT = 0x4000
_GL_NEAREST = 0x2600
_GL_LINEAR = 0x2601

# Capabilities switched off while drawing (and restored): each would change the output.
_CAPS = {
    "blend": 0x0BE2, "depth_test": 0x0B71, "cull_face": 0x0B44, "scissor_test": 0x0C11,
    "stencil_test": 0x0B90, "rasterizer_discard": 0x8C89, "framebuffer_srgb": 0x8DB9,
    "color_logic_op": 0x0BF2, "polygon_offset_fill": 0x8037, "sample_alpha_to_coverage": 0x809E,
}  # fmt: skip
# Integer state saved and restored: (enum, count).
_INTS = {
    "viewport": (0x0BA2, 4), "scissor_box": (0x0C10, 4), "current_program": (0x8B8D, 1),
    "vertex_array": (0x85B5, 1), "draw_framebuffer": (0x8CA6, 1),
    "read_framebuffer": (0x8CAA, 1), "active_texture": (0x84E0, 1),
    "array_buffer": (0x8894, 1), "pixel_pack_buffer": (0x88ED, 1),
    "pixel_unpack_buffer": (0x88EF, 1), "texture_buffer": (0x8C2A, 1),
    "unpack_alignment": (0x0CF5, 1), "unpack_row_length": (0x0CF2, 1),
    "unpack_skip_rows": (0x0CF3, 1), "unpack_skip_pixels": (0x0CF4, 1),
    "pack_alignment": (0x0D05, 1), "pack_row_length": (0x0D02, 1),
    "pack_skip_rows": (0x0D03, 1), "pack_skip_pixels": (0x0D04, 1),
    "polygon_mode": (0x0B40, 2),
}  # fmt: skip
_GL_TEXTURE0 = 0x84C0
_GL_TEXTURE_2D, _GL_TEXTURE_BUFFER = 0x0DE1, 0x8C2A
_GL_TEXTURE_BINDING_2D, _GL_TEXTURE_BINDING_BUFFER = 0x8069, 0x8C2C
_GL_SAMPLER_BINDING = 0x8919
_GL_COLOR_WRITEMASK, _GL_DEPTH_WRITEMASK = 0x0C23, 0x0B72
_GL_COLOR_CLEAR_VALUE, _GL_DEPTH_CLEAR_VALUE = 0x0C22, 0x0B73
_GL_FRONT_AND_BACK, _GL_FILL = 0x0408, 0x1B02
_GL_BUFFERS = {"array_buffer": 0x8892, "pixel_pack_buffer": 0x88EB,
               "pixel_unpack_buffer": 0x88EC, "texture_buffer": 0x8C2A}  # fmt: skip
_GL_PIXEL_STORE = ("unpack_alignment", "unpack_row_length", "unpack_skip_rows",
                   "unpack_skip_pixels", "pack_alignment", "pack_row_length", "pack_skip_rows",
                   "pack_skip_pixels")  # fmt: skip
_TEXTURE_UNITS = 8  # units 0..7: the compensator's samplers and the presentation pass


class GLStateGuard:
    """Saves the host's GL state before LiveRenderer draws and restores it afterwards.

    Saved, set for the drawing, and restored exactly (raw GL, so any host's state, moderngl
    or not): the capabilities blend, depth test, face culling, scissor test, stencil test,
    rasterizer discard, sRGB conversion, colour logic op, polygon offset fill and alpha to
    coverage (all off while drawing); the viewport and scissor box; the colour and depth
    write masks (colour on while drawing); the polygon mode (fill while drawing); the
    current program; the vertex array; the draw and read framebuffers; the active texture
    unit; the 2D and buffer textures and the sampler objects bound on units 0-7 and on
    moderngl's ``default_texture_unit`` (no samplers while drawing); the array,
    pixel-pack, pixel-unpack and texture buffer bindings; the pixel-store alignment, row
    length and skips for packing and unpacking (moderngl's defaults while drawing); the
    clear colour and clear depth; and moderngl's idea of the bound framebuffer
    (``ctx.fbo``). Left as it was because the drawing never touches it: everything else
    (blend function and colour, depth function and range, stencil functions, cull mode,
    front face, line width, point size, primitive restart, uniform buffer bindings,
    textures on other units). Nested uses save and restore once (the outermost).
    """

    def __init__(self, ctx: Any, proc: ProcAddress) -> None:
        c = ctypes
        self.ctx = ctx
        self._depth = 0
        self._saved: dict[str, Any] | None = None
        self._units = sorted({*range(_TEXTURE_UNITS), int(ctx.default_texture_unit)})
        self.get_i = gl_function("glGetIntegerv", (c.c_uint, c.POINTER(c.c_int)), proc)
        self.get_b = gl_function("glGetBooleanv", (c.c_uint, c.POINTER(c.c_ubyte)), proc)
        self.get_f = gl_function("glGetFloatv", (c.c_uint, c.POINTER(c.c_float)), proc)
        self.is_enabled = gl_function("glIsEnabled", (c.c_uint,), proc, restype=c.c_ubyte)
        self.enable = gl_function("glEnable", (c.c_uint,), proc)
        self.disable = gl_function("glDisable", (c.c_uint,), proc)
        self.viewport = gl_function("glViewport", (c.c_int,) * 4, proc)
        self.scissor = gl_function("glScissor", (c.c_int,) * 4, proc)
        self.use_program = gl_function("glUseProgram", (c.c_uint,), proc)
        self.bind_vao = gl_function("glBindVertexArray", (c.c_uint,), proc)
        self.bind_fbo = gl_function("glBindFramebuffer", (c.c_uint, c.c_uint), proc)
        self.active_texture = gl_function("glActiveTexture", (c.c_uint,), proc)
        self.bind_texture = gl_function("glBindTexture", (c.c_uint, c.c_uint), proc)
        self.bind_sampler = gl_function("glBindSampler", (c.c_uint, c.c_uint), proc)
        self.bind_buffer = gl_function("glBindBuffer", (c.c_uint, c.c_uint), proc)
        self.pixel_store = gl_function("glPixelStorei", (c.c_uint, c.c_int), proc)
        self.color_mask = gl_function("glColorMask", (c.c_ubyte,) * 4, proc)
        self.depth_mask = gl_function("glDepthMask", (c.c_ubyte,), proc)
        self.polygon_mode = gl_function("glPolygonMode", (c.c_uint, c.c_uint), proc)
        self.clear_color = gl_function("glClearColor", (c.c_float,) * 4, proc)
        self.clear_depth = gl_function("glClearDepth", (c.c_double,), proc)

    def _ints(self, enum: int, n: int) -> tuple[int, ...]:
        buf = (ctypes.c_int * 4)()
        self.get_i(enum, buf)
        return tuple(buf[:n])

    def snapshot(self) -> dict[str, Any]:
        """The state this guard restores, read from GL (also for tests)."""
        out: dict[str, Any] = {k: bool(self.is_enabled(v)) for k, v in _CAPS.items()}
        for name, (enum, n) in _INTS.items():
            out[name] = self._ints(enum, n)
        mask = (ctypes.c_ubyte * 4)()
        self.get_b(_GL_COLOR_WRITEMASK, mask)
        out["color_writemask"] = tuple(bool(v) for v in mask)
        self.get_b(_GL_DEPTH_WRITEMASK, mask)
        out["depth_writemask"] = bool(mask[0])
        f = (ctypes.c_float * 4)()
        self.get_f(_GL_COLOR_CLEAR_VALUE, f)
        out["clear_color"] = tuple(f)
        self.get_f(_GL_DEPTH_CLEAR_VALUE, f)
        out["clear_depth"] = float(f[0])
        active = out["active_texture"][0]
        units = {}
        for u in self._units:
            self.active_texture(_GL_TEXTURE0 + u)
            units[u] = (self._ints(_GL_TEXTURE_BINDING_2D, 1)[0],
                        self._ints(_GL_TEXTURE_BINDING_BUFFER, 1)[0],
                        self._ints(_GL_SAMPLER_BINDING, 1)[0])  # fmt: skip
        self.active_texture(active)
        out["units"] = units
        return out

    def __enter__(self) -> GLStateGuard:
        self._depth += 1
        if self._depth > 1:
            return self
        self._saved = self.snapshot()
        self._fbo = getattr(self.ctx, "fbo", None)
        for enum in _CAPS.values():
            self.disable(enum)
        self.color_mask(1, 1, 1, 1)
        self.polygon_mode(_GL_FRONT_AND_BACK, _GL_FILL)
        for name in _GL_PIXEL_STORE:
            self.pixel_store(_INTS[name][0], 1 if name.endswith("alignment") else 0)
        self.bind_buffer(_GL_BUFFERS["pixel_unpack_buffer"], 0)
        self.bind_buffer(_GL_BUFFERS["pixel_pack_buffer"], 0)
        for u in self._units:
            self.bind_sampler(u, 0)
        return self

    def __exit__(self, *exc: object) -> None:
        self._depth -= 1
        if self._depth > 0 or self._saved is None:
            return
        s, self._saved = self._saved, None
        if hasattr(self.ctx, "fbo"):
            self.ctx.fbo = self._fbo
        for name, enum in _CAPS.items():
            (self.enable if s[name] else self.disable)(enum)
        self.viewport(*s["viewport"])
        self.scissor(*s["scissor_box"])
        self.use_program(s["current_program"][0])
        self.bind_vao(s["vertex_array"][0])
        self.bind_fbo(_GL_DRAW_FRAMEBUFFER, s["draw_framebuffer"][0])
        self.bind_fbo(_GL_READ_FRAMEBUFFER, s["read_framebuffer"][0])
        for u, (tex2d, texbuf, sampler) in s["units"].items():
            self.active_texture(_GL_TEXTURE0 + u)
            self.bind_texture(_GL_TEXTURE_2D, tex2d)
            self.bind_texture(_GL_TEXTURE_BUFFER, texbuf)
            self.bind_sampler(u, sampler)
        self.active_texture(s["active_texture"][0])
        for name, target in _GL_BUFFERS.items():
            self.bind_buffer(target, s[name][0])
        for name in _GL_PIXEL_STORE:
            self.pixel_store(_INTS[name][0], s[name][0])
        self.color_mask(*s["color_writemask"])
        self.depth_mask(s["depth_writemask"])
        self.polygon_mode(_GL_FRONT_AND_BACK, s["polygon_mode"][0])
        self.clear_color(*s["clear_color"])
        self.clear_depth(s["clear_depth"])


class RawGL:
    """The few raw GL calls moderngl lacks, through ctypes (which releases the GIL).

    glBlitFramebuffer with scaling (moderngl's copy_framebuffer does not scale) and
    glFinish (moderngl's holds the GIL while llvmpipe renders).
    """

    def __init__(self, proc: ProcAddress) -> None:
        uint = ctypes.c_uint
        self._bind = gl_function("glBindFramebuffer", (uint, uint), proc)
        self._blit = gl_function("glBlitFramebuffer", (*[ctypes.c_int] * 8, uint, uint), proc)
        self.finish = gl_function("glFinish", (), proc)

    def blit(
        self,
        src: moderngl.Framebuffer,
        src_rect: tuple[int, int, int, int],
        dst: moderngl.Framebuffer,
        dst_rect: tuple[int, int, int, int],
        linear: bool,
    ) -> None:
        sx, sy, sw, sh = src_rect
        dx, dy, dw, dh = dst_rect
        self._bind(_GL_READ_FRAMEBUFFER, src.glo)
        self._bind(_GL_DRAW_FRAMEBUFFER, dst.glo)
        self._blit(
            sx,
            sy,
            sx + sw,
            sy + sh,
            dx,
            dy,
            dx + dw,
            dy + dh,
            _GL_COLOR_BUFFER_BIT,
            _GL_LINEAR if linear else _GL_NEAREST,
        )
        dst.use()  # moderngl's own binding again
