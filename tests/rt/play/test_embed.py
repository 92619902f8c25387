"""The embedding API in a hostile host: GL state restored, only the viewport drawn, and a frame
from the host's own texture equal to the numpy path (headless EGL context)."""

from __future__ import annotations

import ctypes
from typing import Any

import numpy as np
import pytest

from tests.support.calibrations import small_calibration
from tests.support.synthetic import smooth_frame
from viewcomp.calib.model.reference import compensate
from viewcomp.rt.gl.context import gl_function

GW, GH = 64, 32
W, H = 160, 96
BACKGROUND = (51, 102, 153)
OUTLIERS = 6  # pixel-channels > 1 level from the reference per frame (see test_player.py)

GL_BLEND, GL_DEPTH_TEST, GL_CULL_FACE, GL_SCISSOR_TEST = 0x0BE2, 0x0B71, 0x0B44, 0x0C11
GL_VIEWPORT, GL_CURRENT_PROGRAM, GL_VERTEX_ARRAY_BINDING = 0x0BA2, 0x8B8D, 0x85B5
GL_TEXTURE_BINDING_2D, GL_SAMPLER_BINDING, GL_ACTIVE_TEXTURE = 0x8069, 0x8919, 0x84E0
GL_UNPACK_ROW_LENGTH, GL_UNPACK_ALIGNMENT, GL_COLOR_WRITEMASK = 0x0CF2, 0x0CF5, 0x0C23
GL_DRAW_FRAMEBUFFER_BINDING, GL_FRONT_AND_BACK, GL_TEXTURE0 = 0x8CA6, 0x0408, 0x84C0


class Raw:
    """The host's own raw GL calls (independent of the guard under test)."""

    def __init__(self) -> None:
        c = ctypes
        self.enable = gl_function("glEnable", (c.c_uint,))
        self.is_enabled = gl_function("glIsEnabled", (c.c_uint,), restype=c.c_ubyte)
        self.get_i = gl_function("glGetIntegerv", (c.c_uint, c.POINTER(c.c_int)))
        self.get_b = gl_function("glGetBooleanv", (c.c_uint, c.POINTER(c.c_ubyte)))
        self.get_error = gl_function("glGetError", (), restype=c.c_uint)
        self.scissor = gl_function("glScissor", (c.c_int,) * 4)
        self.cull_face = gl_function("glCullFace", (c.c_uint,))
        self.color_mask = gl_function("glColorMask", (c.c_ubyte,) * 4)
        self.pixel_store = gl_function("glPixelStorei", (c.c_uint, c.c_int))
        self.use_program = gl_function("glUseProgram", (c.c_uint,))
        self.bind_vao = gl_function("glBindVertexArray", (c.c_uint,))
        self.active_texture = gl_function("glActiveTexture", (c.c_uint,))

    def ints(self, enum: int, n: int = 1) -> tuple[int, ...]:
        buf = (ctypes.c_int * 4)()
        self.get_i(enum, buf)
        return tuple(buf[:n])

    def mask(self) -> tuple[int, ...]:
        buf = (ctypes.c_ubyte * 4)()
        self.get_b(GL_COLOR_WRITEMASK, buf)
        return tuple(buf)


@pytest.fixture
def host(gl_ctx: Any) -> Any:
    """A host's framebuffer (colour + depth) and its objects, with hostile state left on."""
    import moderngl

    ctx = gl_ctx
    raw = Raw()
    color = ctx.texture((W, H), 4, dtype="f1")
    depth = ctx.depth_renderbuffer((W, H))
    fbo = ctx.framebuffer(color_attachments=[color], depth_attachment=depth)
    prog = ctx.program(
        vertex_shader="#version 330 core\nvoid main() { gl_Position = vec4(0.0); }",
        fragment_shader="#version 330 core\nout vec4 c;\nvoid main() { c = vec4(1.0); }",
    )
    vao = ctx.vertex_array(prog, [])
    host_tex = ctx.texture((4, 4), 4, dtype="f1")
    sampler = ctx.sampler(filter=(moderngl.LINEAR, moderngl.LINEAR))
    objects = [color, depth, fbo, prog, vao, host_tex, sampler]

    def hostile() -> None:
        fbo.use()
        ctx.viewport = (0, 0, W, H)
        fbo.clear(*(v / 255.0 for v in BACKGROUND), 1.0, depth=0.0)  # GL_LESS rejects all
        ctx.blend_func = moderngl.ONE, moderngl.ONE  # additive
        raw.enable(GL_BLEND)
        raw.enable(GL_DEPTH_TEST)
        raw.enable(GL_CULL_FACE)
        raw.cull_face(GL_FRONT_AND_BACK)  # culls every triangle
        raw.enable(GL_SCISSOR_TEST)
        raw.scissor(0, 0, 3, 3)
        raw.color_mask(1, 0, 1, 1)  # no green
        raw.pixel_store(GL_UNPACK_ROW_LENGTH, 7)
        raw.pixel_store(GL_UNPACK_ALIGNMENT, 8)
        ctx.viewport = (5, 6, 70, 40)
        host_tex.use(0)
        host_tex.use(1)
        sampler.use(0)
        raw.use_program(prog.glo)
        raw.bind_vao(vao.glo)
        raw.active_texture(GL_TEXTURE0 + 3)

    from viewcomp.rt.gl.context import default_proc_address
    from viewcomp.rt.play.embed import GLStateGuard

    with GLStateGuard(ctx, default_proc_address()):  # the session context as it was, after
        yield dict(ctx=ctx, raw=raw, fbo=fbo, prog=prog, vao=vao, tex=host_tex,
                   sampler=sampler, hostile=hostile)  # fmt: skip
        sampler.clear(0)
    for o in reversed(objects):
        o.release()


def _read(fbo: Any) -> np.ndarray:
    """The host framebuffer as (H, W, 3), row 0 on top (read without the host's state)."""
    data = np.frombuffer(fbo.read(components=3, alignment=1), np.uint8)
    return data.reshape(H, W, 3)[::-1]


def _region(img: np.ndarray, vp: tuple[int, int, int, int]) -> np.ndarray:
    x, y, w, h = vp
    return img[H - y - h : H - y, x : x + w]


@pytest.mark.gl
def test_hostile_host_state_is_restored_and_only_the_viewport_drawn(host: dict) -> None:
    from viewcomp.rt.play.embed import LiveRenderer

    ctx, raw = host["ctx"], host["raw"]
    cal = small_calibration(GW, GH, screen="magenta")
    frame = smooth_frame(GW, GH, seed=3)
    vp = (40, 20, GW, GH)
    with LiveRenderer(cal, ctx, angle=60.0, eye_tau=0.0, async_tone=False,
                      tone_tau=None) as live:  # fmt: skip
        host["hostile"]()
        before = live.state_guard.snapshot()
        record = live.render(frame, target=host["fbo"], viewport=vp)
        after = live.state_guard.snapshot()
        assert raw.get_error() == 0
        assert after == before
        # the host's own view of its state, independently of the guard
        for cap in (GL_BLEND, GL_DEPTH_TEST, GL_CULL_FACE, GL_SCISSOR_TEST):
            assert raw.is_enabled(cap) == 1
        assert raw.ints(GL_VIEWPORT, 4) == (5, 6, 70, 40)
        assert raw.ints(GL_CURRENT_PROGRAM) == (host["prog"].glo,)
        assert raw.ints(GL_VERTEX_ARRAY_BINDING) == (host["vao"].glo,)
        assert raw.ints(GL_ACTIVE_TEXTURE) == (GL_TEXTURE0 + 3,)
        assert raw.ints(GL_UNPACK_ROW_LENGTH) == (7,) and raw.ints(GL_UNPACK_ALIGNMENT) == (8,)
        assert raw.ints(GL_DRAW_FRAMEBUFFER_BINDING) == (host["fbo"].glo,)
        assert raw.mask() == (1, 0, 1, 1)
        raw.active_texture(GL_TEXTURE0)
        assert raw.ints(GL_TEXTURE_BINDING_2D) == (host["tex"].glo,)
        sampler = raw.ints(GL_SAMPLER_BINDING)[0]
        assert sampler != 0 and before["units"][0][2] == sampler  # the host's sampler
        raw.active_texture(GL_TEXTURE0 + 3)
        assert ctx.fbo is host["fbo"]  # moderngl's own idea of the bound framebuffer
        raw.color_mask(1, 1, 1, 1)
        shot = _read(host["fbo"])
        p = record.params
        want = compensate(p.model, frame, record.eye, p.alpha, p.beta)
        d = np.abs(_region(shot, vp).astype(int) - want.astype(int))
        print(f"\nhostile host: inside the viewport max {d.max()} level(s), "
              f"{int((d > 1).sum())} pixel-channel(s) over 1")  # fmt: skip
        assert int((d > 1).sum()) <= OUTLIERS
        outside = shot.copy()
        x, y, w, h = vp
        outside[H - y - h : H - y, x : x + w] = BACKGROUND
        assert np.all(outside == np.array(BACKGROUND, np.uint8))  # nothing else touched
        assert live.live_objects() > 0
    assert live.live_objects() == 0


@pytest.mark.gl
@pytest.mark.parametrize("top_down", [False, True])
def test_texture_input_equals_the_numpy_path(host: dict, top_down: bool) -> None:
    from viewcomp.rt.play.embed import LiveRenderer

    ctx = host["ctx"]
    cal = small_calibration(GW, GH, screen="magenta")
    frame = smooth_frame(GW, GH, seed=4)
    rgba = np.concatenate([frame, np.full((GH, GW, 1), 255, np.uint8)], axis=2)
    tex = ctx.texture((GW, GH), 4, np.ascontiguousarray(rgba if top_down else rgba[::-1]))
    big_rgba = np.repeat(np.repeat(rgba, 2, axis=0), 2, axis=1)  # a 2x frame: scaled on the GPU
    big = ctx.texture((2 * GW, 2 * GH), 4, np.ascontiguousarray(big_rgba if top_down
                                                                 else big_rgba[::-1]))  # fmt: skip
    a, b, c = (8, 8, GW, GH), (80, 8, GW, GH), (8, 50, GW, GH)
    try:
        host["hostile"]()  # also while it is made: its uploads must not follow the host's state
        with LiveRenderer(cal, ctx, angle=60.0, eye_tau=0.0, async_tone=False,
                          tone_tau=None) as live:  # fmt: skip
            before = live.state_guard.snapshot()
            r1 = live.render(frame, target=host["fbo"], viewport=a, now=1.0)
            r2 = live.render_texture(tex.glo, (GW, GH), target=host["fbo"], viewport=b,
                                     top_down=top_down, now=1.0)  # fmt: skip
            r3 = live.render_texture(big.glo, (2 * GW, 2 * GH), target=host["fbo"],
                                     viewport=c, top_down=top_down, now=1.0)  # fmt: skip
            assert live.state_guard.snapshot() == before
            host["raw"].color_mask(1, 1, 1, 1)
            shot = _read(host["fbo"])
        assert np.array_equal(r1.eye, r2.eye)
        assert (r1.params.alpha, r1.params.beta) == (r2.params.alpha, r2.params.beta)
        d = np.abs(_region(shot, a).astype(int) - _region(shot, b).astype(int))
        d3 = np.abs(_region(shot, a).astype(int) - _region(shot, c).astype(int))
        print(f"\ntexture vs numpy (top_down={top_down}): max {d.max()} level(s); a 2x texture "
              f"scaled on the GPU: max {d3.max()}, mean {d3.mean():.3f}; tone "
              f"{r1.params.alpha:.3f}/{r3.params.alpha:.3f}")  # fmt: skip
        assert int(d.max()) <= 1
        assert float(d3.mean()) < 0.5
        tex.read()  # the host's texture is still the host's (not released by the wrapper)
    finally:
        tex.release()
        big.release()


@pytest.mark.gl
def test_texture_input_refuses_what_it_cannot_sample(gl_ctx: Any) -> None:
    from viewcomp.rt.play.embed import LiveRenderer

    cal = small_calibration(GW, GH, screen="magenta")
    with LiveRenderer(cal, gl_ctx, async_tone=False) as live:
        with pytest.raises(ValueError, match="dtype"):
            live.render_texture(1, (GW, GH), dtype="u1")
        with pytest.raises(ValueError, match="components"):
            live.render_texture(1, (GW, GH), components=2)
