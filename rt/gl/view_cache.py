"""The GL compensator's view cache: for a held eye the pixel method's per-pixel solve is done
once and each draw reads it (~0.65x the time at 1080p on llvmpipe).

For a held eye the pixel method's solve is linear in the tone map, so G = M^-1 Ww,
a = M^-1 Aw, b = M^-1 1 and d = M^-1 Ac are rendered once per eye (5 texels per pixel, in
``view_steps`` bands, each band copied into a buffer texture) and each draw reads those
instead of solving. Only a moving eye pays the full solve every draw.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from viewcomp.calib.world.audience import Audience
from viewcomp.rt.gl.shader_passes import (
    _ADAPTIVE,
    _ADAPTIVE_CACHED,
    _AUDIENCE,
    _BUILD_AUDIENCE,
    _BUILD_VIEW,
    _CACHED,
    _METHODS,
    _SAMPLERS,
    _VIEW_TEXELS,
)

if TYPE_CHECKING:
    import moderngl

    from viewcomp.calib.model.gamut import ToneField
    from viewcomp.rt.gl.context import BufferTexture


class ViewCache:
    """The view cache of :class:`~viewcomp.rt.gl.compensator.Compensator` (a mixin)."""

    ctx: moderngl.Context
    method: str
    eye: np.ndarray
    audience: Audience | None
    field: ToneField | None
    width: int
    height: int
    view_cache: bool
    view_hold: int
    view_steps: int
    _identity: bool
    _consts: dict[str, str | int]
    _units: list[tuple[int, Any]]
    _view: tuple[Any, Any] | None
    _view_eye: tuple[float, ...] | None
    _last_eye: tuple[float, ...] | None
    _held: int
    _building: tuple[float, ...] | None
    _band_row: int

    if TYPE_CHECKING:  # the compensator's own, declared for the type checker

        def _track(self, obj: Any) -> Any: ...

        def _tex(self, size: tuple[int, int], comps: int, dtype: str, data: Any = None) -> Any: ...

        def _buffer_texture(self, data: np.ndarray | int, fmt: str) -> BufferTexture: ...

        def _render(self, method: int, flip_y: int) -> None: ...

    def _view_block(self, n: int) -> tuple[int, int]:
        """(bx, by): ``n`` texels of a pixel as a bx x by block of the view cache's target.

        One row of ``n`` texels if ``n * W`` fits the driver's GL_MAX_TEXTURE_SIZE, else the
        fewest rows that fit (3 x 2 for 5 texels at 3840 wide on llvmpipe's 16384).
        """
        max_size = int(self.ctx.info["GL_MAX_TEXTURE_SIZE"])
        for by in range(1, n + 1):
            bx = -(-n // by)
            if bx * self.width <= max_size and by * self.height <= max_size:
                return bx, by
        raise ValueError(
            f"grid {self.width}x{self.height} too large for the view cache "
            f"(GL_MAX_TEXTURE_SIZE {max_size}); use view_cache=False"
        )

    def _shader_method(self) -> int:
        """The shader METHOD for the next draw (:meth:`_view_method`), the adaptive tone
        map's variant of it when a field is set and one eye is seen."""
        method = self._view_method()
        if self.field is None or self.audience is not None:
            return method
        return {_CACHED: _ADAPTIVE_CACHED, _METHODS["pixel"]: _ADAPTIVE}.get(method, method)

    def _view_method(self) -> int:
        """The shader METHOD of the global tone map for the next draw; advances the view
        cache when it is due.

        The pixel method runs from the view cache (METHOD 3, ~0.7x the time on llvmpipe)
        when the eye (or the audience) is the one the cache was built for: an audience's
        cache holds its combined solve, so a held audience costs what a held eye does. The
        cache is (re)built once the view has been the same for ``view_hold`` draws in a row
        (a held viewer, a constant ``--angle``), in ``view_steps`` bands of rows, one band
        before each draw, so that no single draw takes much longer than the others; until it
        is complete, and while the view keeps moving, every draw solves in full (METHOD 1, or
        5 for an audience).
        """
        if self._identity:
            return 0
        if self.method != "pixel":
            return _METHODS[self.method]
        aud = self.audience
        view = tuple(float(v) for v in self.eye) if aud is None else (-1.0, *aud.key)
        if view == self._last_eye:
            self._held += 1
        else:
            self._last_eye, self._held = view, 0
        if view == self._view_eye:
            return _CACHED
        build = _BUILD_VIEW if aud is None else _BUILD_AUDIENCE
        if self.view_cache and self._held >= self.view_hold and self._build_view_band(view, build):
            return _CACHED
        return _METHODS["pixel"] if aud is None else _AUDIENCE

    def _build_view_band(self, eye: tuple[float, ...], build: int = _BUILD_VIEW) -> bool:
        """Render the next band of the view cache for the view ``eye`` (an eye, or an
        audience's key) with shader ``build``; True once it is complete."""
        bx, by = self._view_block(_VIEW_TEXELS)
        size = (bx * self.width, by * self.height)
        row_bytes = 16 * size[0]
        if self._view is None:
            fbo = self._track(self.ctx.framebuffer(color_attachments=[self._tex(size, 4, "f4")]))
            view = self._buffer_texture(row_bytes * size[1], "rgba32f")
            self._view = (view, fbo)
            self._consts["VIEW_BX"], self._consts["VIEW_BY"] = bx, by
            self._units[_SAMPLERS.index("u_view")] = (_SAMPLERS.index("u_view"), view)
        if self._building != eye:  # a new eye: start over (the old bands are stale)
            self._building, self._band_row = eye, 0
            self._view_eye = None
        view, fbo = self._view
        rows = -(-self.height // max(1, self.view_steps))
        r0, r1 = self._band_row, min(self.height, self._band_row + rows)
        band = (0, by * r0, size[0], by * (r1 - r0))
        fbo.viewport = (0, 0, *size)
        fbo.scissor = band
        fbo.use()
        self._render(build, flip_y=0)
        fbo.scissor = None
        # Into the buffer texture the draws read (a copy within the driver, no round trip).
        fbo.read_into(
            view.buffer, viewport=band, components=4, dtype="f4", write_offset=row_bytes * by * r0
        )
        self._band_row = r1
        if r1 < self.height:
            return False
        self._view_eye, self._building = eye, None
        return True
