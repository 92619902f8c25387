"""A frame from one of the host's GL textures into :class:`~viewcomp.rt.play.embed.LiveRenderer`:
fitted to the grid on the GPU, copied into the compensator's input within the driver."""

from __future__ import annotations

import time
from typing import TYPE_CHECKING, Any

import numpy as np

from viewcomp.calib.comp.compensation import thumbnail
from viewcomp.rt.media.frames import fit_rect

if TYPE_CHECKING:
    import moderngl

    from viewcomp.rt.gl.compensator import Compensator
    from viewcomp.rt.gl.state_guard import GLStateGuard
    from viewcomp.rt.play.embed_present import ScaleFilter
    from viewcomp.rt.play.frame_record import FrameRecord
    from viewcomp.rt.play.tone_worker import ToneWorker


class TextureInput:
    """The texture path of :class:`~viewcomp.rt.play.embed.LiveRenderer` (a mixin)."""

    ctx: moderngl.Context
    grid: tuple[int, int]
    scale: ScaleFilter
    tone_side: int
    compensator: Compensator
    _tone: ToneWorker | None
    _tone_period: float
    _tex_in: tuple[Any, Any, Any, Any] | None
    _tex_thumb: tuple[np.ndarray, float] | None

    if TYPE_CHECKING:  # the renderer's own, declared for the type checker

        @property
        def state_guard(self) -> GLStateGuard: ...

        def _presenter(self) -> tuple[Any, Any, Any, Any]: ...

        def _track(self, obj: Any) -> Any: ...

        def _set_frame(self, thumb: np.ndarray, now: float, frame: Any) -> FrameRecord: ...

        def draw(
            self,
            target: moderngl.Framebuffer,
            viewport: tuple[int, int, int, int] | None = None,
            size: tuple[int, int] | None = None,
            clear: bool = False,
        ) -> None: ...

    def prepare_texture(
        self,
        texture: int,
        size: tuple[int, int],
        components: int = 4,
        dtype: str = "f1",
        top_down: bool = False,
        now: float | None = None,
    ) -> FrameRecord:
        """Take the frame from a texture of the host's (same context) instead of numpy.

        Args:
            texture: the host's GL texture name (``GL_TEXTURE_2D``, not multisampled).
            size: its (width, height) in texels; any size: fitted to the grid (aspect
                kept, centred on black) on the GPU, nearest when it is the grid's size,
                else the ``scale`` filter (linear for "auto").
            components: 3 (RGB) or 4 (RGBA; alpha ignored).
            dtype: its texel type in moderngl's names: ``"f1"`` (8-bit normalised, e.g.
                GL_RGBA8), ``"f2"`` or ``"f4"`` (half or full float, 0..1 = black..white).
            top_down: False (GL's convention) when texel row 0 is the picture's bottom row,
                True when it is the top row (e.g. uploaded from an image array as is).

        The host's texture is only read (its parameters are not changed: a sampler object
        of ours is bound while it is drawn). Equals :meth:`prepare` of the same picture as
        numpy within one level (the tone map's thumbnail is taken from the same grid).
        """
        if dtype not in ("f1", "f2", "f4"):
            raise ValueError(f"dtype is 'f1', 'f2' or 'f4' (normalised or float), got {dtype!r}")
        if components not in (3, 4):
            raise ValueError(f"components is 3 (RGB) or 4 (RGBA), got {components}")
        tw, th = (int(v) for v in size)
        if tw < 1 or th < 1:
            raise ValueError(f"size is (width, height) >= 1, got {size}")
        now = time.monotonic() if now is None else now
        with self.state_guard:
            fbo, pbo, nearest, linear = self._texture_input()
            gw, gh = self.grid
            x0, y0, fw, fh = fit_rect(tw, th, gw, gh)
            host = self.ctx.external_texture(int(texture), (tw, th), components, 0, dtype)
            try:
                fbo.use()
                fbo.clear(0.0, 0.0, 0.0, 1.0)
                # The rows go into the input in the order upload() takes an array (row 0 =
                # the picture's top first): the framebuffer's bottom row is the top row.
                self.ctx.viewport = (x0, y0, fw, fh)
                exact = (fw, fh) == (tw, th) or self.scale == "nearest"
                sampler = nearest if exact else linear
                sampler.use(0)
                host.use(0)
                _, _, prog, vao = self._presenter()
                prog["u_image"].value = 0
                if "u_flip_y" in prog:
                    prog["u_flip_y"].value = 0 if top_down else 1
                vao.render(vertices=3)
                if "u_flip_y" in prog:
                    prog["u_flip_y"].value = 0
                sampler.clear(0)
                fbo.read_into(pbo, components=3, alignment=1)
            finally:
                host.release()  # the wrapper only: an external texture stays the host's
            self.compensator.upload_buffer(pbo)
            return self._set_frame(self._texture_thumb(pbo, now), now, None)

    def _texture_input(self) -> tuple[Any, Any, Any, Any]:
        """(framebuffer, pixel buffer, nearest and linear samplers) of the texture path."""
        if self._tex_in is None:
            import moderngl

            w, h = self.grid
            tex = self._track(self.ctx.texture((w, h), 4, dtype="f1"))
            fbo = self._track(self.ctx.framebuffer(color_attachments=[tex]))
            pbo = self._track(self.ctx.buffer(reserve=w * h * 3))
            samplers = [
                self._track(self.ctx.sampler(filter=(f, f), repeat_x=False, repeat_y=False))
                for f in (moderngl.NEAREST, moderngl.LINEAR)
            ]
            self._tex_in = (fbo, pbo, samplers[0], samplers[1])
        return self._tex_in

    def _texture_thumb(self, pbo: Any, now: float) -> np.ndarray:
        """The tone map's thumbnail of the grid-sized input: read back only when the tone
        map can take a new one (every frame without ``async_tone``)."""
        last = self._tex_thumb
        if last is None or self._tone is None or now - last[1] >= self._tone_period:
            w, h = self.grid
            grid = np.frombuffer(pbo.read(), np.uint8).reshape(h, w, 3)
            last = self._tex_thumb = (thumbnail(grid, self.tone_side), now)
        return last[0]

    def render_texture(
        self,
        texture: int,
        size: tuple[int, int],
        target: moderngl.Framebuffer | None = None,
        viewport: tuple[int, int, int, int] | None = None,
        *,
        components: int = 4,
        dtype: str = "f1",
        top_down: bool = False,
        now: float | None = None,
    ) -> FrameRecord:
        """:meth:`prepare_texture` then :meth:`draw`: a frame already in a host texture."""
        with self.state_guard:
            record = self.prepare_texture(texture, size, components, dtype, top_down, now)
            self.draw(self.ctx.screen if target is None else target, viewport)
        return record
