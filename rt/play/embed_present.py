"""Drawing :class:`~viewcomp.rt.play.embed.LiveRenderer`'s frame into the host's target:
directly at the grid's size, else through an off-screen grid scaled into the viewport; the
warm-up that compiles the shaders before the first frame; blits and finishing."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from viewcomp.rt.gl.state_guard import GLStateGuard, RawGL
from viewcomp.rt.media.frames import Planes
from viewcomp.shaders import build_program

if TYPE_CHECKING:
    import moderngl

    from viewcomp.rt.gl.compensator import Compensator
    from viewcomp.rt.gl.context import ProcAddress

ScaleFilter = Literal["auto", "linear", "nearest"]


def moderngl_filter(nearest: bool) -> int:
    """moderngl's NEAREST or LINEAR constant."""
    import moderngl

    return moderngl.NEAREST if nearest else moderngl.LINEAR


def fit_viewport(grid: tuple[int, int], size: tuple[int, int]) -> tuple[int, int, int, int]:
    """(x, y, w, h) of a grid (W, H) scaled to fit a target (W, H), aspect kept, centred."""
    gw, gh = grid
    tw, th = size
    if (gw, gh) == (tw, th):
        return 0, 0, tw, th
    s = min(tw / gw, th / gh)
    w, h = max(1, round(gw * s)), max(1, round(gh * s))
    return (tw - w) // 2, (th - h) // 2, w, h


class Presentation:
    """The drawing side of :class:`~viewcomp.rt.play.embed.LiveRenderer` (a mixin)."""

    ctx: moderngl.Context
    grid: tuple[int, int]
    scale: ScaleFilter
    compensator: Compensator
    _guard: GLStateGuard
    _proc: ProcAddress
    _raw: RawGL | None
    _present: tuple[Any, Any, Any, Any] | None
    _objects: list[Any]

    @property
    def state_guard(self) -> GLStateGuard:
        """The guard that saves and restores the host's GL state around every call."""
        return self._guard

    def draw(
        self,
        target: moderngl.Framebuffer,
        viewport: tuple[int, int, int, int] | None = None,
        size: tuple[int, int] | None = None,
        clear: bool = False,
    ) -> None:
        """Draw the prepared frame into ``target`` at ``viewport`` (x, y, w, h; GL window
        coordinates, origin bottom-left; default: the grid fitted into the target).

        ``size`` is the target's (W, H) (default ``target.size``; a window's default
        framebuffer may have been resized since the context was made). At the grid's size
        the shader writes the viewport directly; at any other size it renders the grid
        off-screen and scales it into the viewport (``scale`` filter). Only the viewport's
        pixels are written, unless ``clear``: then the rest of the target is cleared to
        black first (the player's letterbox; a host keeps its own pixels).
        """
        with self.state_guard:
            self._draw_into(target, viewport, size, clear)

    def _draw_into(
        self,
        target: moderngl.Framebuffer,
        viewport: tuple[int, int, int, int] | None,
        size: tuple[int, int] | None,
        clear: bool,
    ) -> None:
        tw, th = size if size is not None else tuple(target.size)
        if viewport is None:
            viewport = fit_viewport(self.grid, (tw, th))
        x, y, w, h = viewport
        if clear and (x, y, w, h) != (0, 0, tw, th):
            target.use()
            self.ctx.viewport = (0, 0, tw, th)
            target.clear(0.0, 0.0, 0.0, 1.0, viewport=(0, 0, tw, th))
        if (w, h) == self.grid:
            self.compensator.render_to(target, origin=(x, y), flip_y=True)
            return
        tex, fbo, prog, vao = self._presenter()
        self.compensator.render_to(fbo, origin=(0, 0), flip_y=True)
        gw, gh = self.grid
        nearest = self.scale == "nearest" or (self.scale == "auto" and w % gw == 0 and h % gh == 0)
        f = moderngl_filter(nearest)
        tex.filter = (f, f)
        target.use()
        self.ctx.viewport = (x, y, w, h)
        tex.use(0)
        prog["u_image"].value = 0
        vao.render(vertices=3)

    def warm_up(self, planes: bool = True, present: bool = False) -> None:
        """Compile the shader variant for yuv420p ``planes`` (else RGB) input, and the
        presentation pass with ``present``, by drawing a black frame off-screen once, so the
        first real frame is not late. The tone map is not touched."""
        with self.state_guard:
            self._warm_up(planes, present)

    def _warm_up(self, planes: bool, present: bool) -> None:
        w, h = self.grid
        if planes:
            cw, ch = (w + 1) // 2, (h + 1) // 2
            chroma = np.full((ch, cw), 128, np.uint8)
            black = Planes(np.full((h, w), 16, np.uint8), chroma, chroma.copy())
            self.compensator.upload_planes(black)
        else:
            self.compensator.upload(np.zeros((h, w, 3), np.uint8))
        tex, fbo, prog, vao = self._presenter()
        self.compensator.render_to(fbo, origin=(0, 0), flip_y=True)
        if present:  # into the default framebuffer's back buffer, overwritten before a swap
            self.ctx.screen.use()
            self.ctx.viewport = (0, 0, w, h)
            tex.use(0)
            prog["u_image"].value = 0
            vao.render(vertices=3)
        self.finish()

    def _presenter(self) -> tuple[Any, Any, Any, Any]:
        """(texture, framebuffer, program, vertex array) of the grid -> viewport pass."""
        if self._present is None:
            tex = self._track(self.ctx.texture(self.grid, 4, dtype="f1"))
            tex.repeat_x = tex.repeat_y = False
            fbo = self._track(self.ctx.framebuffer(color_attachments=[tex]))
            prog = self._track(build_program(self.ctx, "fullscreen.vert.glsl", "present.frag.glsl"))
            vao = self._track(self.ctx.vertex_array(prog, []))
            self._present = (tex, fbo, prog, vao)
        return self._present

    def _gl(self) -> RawGL:
        if self._raw is None:
            self._raw = RawGL(self._proc)
        return self._raw

    def finish(self) -> None:
        """Wait until the GPU has finished drawing, without holding Python's GIL."""
        self._gl().finish()

    def blit(
        self,
        src: moderngl.Framebuffer,
        src_rect: tuple[int, int, int, int],
        dst: moderngl.Framebuffer,
        dst_rect: tuple[int, int, int, int],
        linear: bool = False,
    ) -> None:
        """Copy a rectangle between framebuffers of this context, scaling (for overlays)."""
        with self.state_guard:
            self._gl().blit(src, src_rect, dst, dst_rect, linear)

    def _track(self, obj: Any) -> Any:
        self._objects.append(obj)
        return obj
