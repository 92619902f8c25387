"""The GL compensator: the formula of docs/RUNTIME.md in a fragment shader, embeddable.

:class:`Compensator` owns every GL object it uses (program, vertex array, textures, an
RGBA8 framebuffer) and releases them all in :meth:`Compensator.release` (or on leaving a
``with`` block). It never scales: frames must be exactly the model's (H, W) grid.

Speed on llvmpipe (docs/BENCHMARKS.md) shapes the GL side:

- the frame is read with NEAREST ``textureLod(.., 0)`` at texel centres (llvmpipe runs
  ``texelFetch`` on 2D textures ~1.5x slower); the LUTs, the maps and the view cache are
  buffer textures (:class:`viewcomp.rt.gl.context.BufferTexture`) read with ``texelFetch``,
  ~0.7x the cost of the 2D reads; draws are flushed at once and waited for with the GIL
  released (:func:`viewcomp.rt.gl.context.finish`), so other threads run meanwhile;
- what is fixed for this object (grid size, LUT domain, lobe) is compiled in as ``#define``
  literals (one program per variant and Compensator, ~0.1-0.3 s at start), what changes
  per frame is handed over as flat inputs by the vertex shader
  (:meth:`Compensator._frame_values`): the same numbers in a uniform block read by the
  fragment shader cost 10-20 % more per draw at 1080p (``bench/bench_uniforms.py``);
- the pixel method's 31 per-pixel values are 8 float32 RGBA texels per pixel
  (:func:`pixel_texels`), side by side in one buffer so that a pixel's texels are
  neighbours in memory (half the cost of 8 separate textures on llvmpipe);
- the view cache: for a held eye the pixel method's solve is linear in the tone map, so
  G = M^-1 Ww, a = M^-1 Aw, b = M^-1 1 and d = M^-1 Ac are rendered once per eye (5 texels
  per pixel, in ``view_steps`` bands, each band copied into a buffer texture) and each draw
  reads those instead of solving (~0.65x the time at 1080p). Only a moving eye pays the
  full solve every draw.

The CPU side of the formula that both this class and the mpv export
(:mod:`viewcomp.rt.export.mpv`) need is numpy only and lives once in
:mod:`viewcomp.calib.model.shader_inputs`: ``pixel_texels`` (the per-pixel maps' layout),
``inverse_position`` (the inverse LUT's squared position) and ``paper_rows`` (the paper
method's folded matrices).

Typical use::

    with Compensator(model) as comp:
        comp.set_angle(60.0, distance=0.5, height=0.035)
        comp.set_tone(alpha, beta)
        out = comp.render(frame)              # (H, W, 3) uint8 -> (H, W, 3) uint8

Threading: call it from the thread whose GL context is current (the thread that made it).
"""

from __future__ import annotations

import itertools
import math
from typing import Any

import moderngl
import numpy as np

from viewcomp.calib.model.reference import lut_forward
from viewcomp.calib.model.runtime import RuntimeModel
from viewcomp.calib.model.shader_inputs import (  # noqa: F401 (pixel_texels etc. re-exported)
    MAP_TEXELS,
    as_f32,
    inv_pairs,
    inverse_position,
    inverse_scale,
    lobe_table,
    paper_rows,
    pixel_texel_blocks,
    pixel_texels,
)
from viewcomp.calib.world.audience import MAX_VIEWERS, Audience
from viewcomp.calib.world.eye import eye_from_angle
from viewcomp.rt.gl.context import (
    BufferTexture,
    ProcAddress,
    create_context,
    finish,
    flush,
    set_sampler_units,
)
from viewcomp.rt.media.frames import Planes, yuv_coefficients
from viewcomp.shaders import build_program, vec_literal

_METHODS = {"identity": 0, "pixel": 1, "paper": 2}
_CACHED, _BUILD_VIEW = 3, 4  # shader METHODs of the pixel method's view cache
_AUDIENCE, _BUILD_AUDIENCE = 5, 6  # an audience: solved per draw, its view cache
_VIEW_TEXELS = 5  # per pixel in the view cache: rows of G | a, b, d
_PATHS = {0: "identity", 1: "solve", 2: "paper", _CACHED: "cached", _AUDIENCE: "audience"}
_SAMPLERS = "u_rgb u_y u_uv u_fwd u_inv u_maps u_view u_lobe".split()


class Compensator:
    """Runs the compensation shader for one :class:`RuntimeModel` on an (H, W) grid.

    Args:
        model: the runtime model (method ``pixel`` or ``paper``; ``identity`` also works and
            needs only the LUTs). Per-pixel arrays are uploaded once here.
        ctx: a moderngl context (>= 3.3) current on this thread; ``None`` creates a
            standalone EGL one, which this object then owns and releases.
        view_cache: pixel method: once the eye has been the same for ``view_hold`` draws in
            a row, solve the per-pixel system for that eye once (an extra ~5 draws' work)
            and draw from that cache (~0.7x the per-frame time on llvmpipe) until the eye
            moves. False: always solve per draw. Attributes of the same names, settable.
        view_hold: draws with an unchanged eye before the cache is built (>= 0).
        view_steps: the cache is built in this many bands of rows, one before each draw
            (>= 1; 1: at once, the least work; more: no draw takes much longer than others).
        gl_loader: the GL function loader (name -> address) of the host's windowing
            library, for the few calls moderngl lacks (buffer textures); default EGL's.

    State defaults: eye = ``model.cam_eye``, alpha = 1, beta = 0, compensation on.

    Raises:
        ValueError: a model of the wrong shapes or with non-finite values, naming the array.
        GLUnavailable: ``ctx`` is None and no OpenGL 3.3 context can be made.
    """

    def __init__(
        self,
        model: RuntimeModel,
        ctx: moderngl.Context | None = None,
        view_cache: bool = True,
        view_hold: int = 1,
        view_steps: int = 4,
        gl_loader: ProcAddress | None = None,
    ) -> None:
        if not isinstance(model, RuntimeModel):
            raise ValueError(f"model must be a RuntimeModel, got {type(model).__name__}")
        if int(view_hold) < 0 or int(view_steps) < 1:
            raise ValueError(
                f"need view_hold >= 0 and view_steps >= 1, got {view_hold} and {view_steps}"
            )
        self.view_cache = bool(view_cache)
        self.view_hold = int(view_hold)
        self.view_steps = int(view_steps)
        self._loader = gl_loader
        self._own_ctx = ctx is None
        self.ctx: moderngl.Context = create_context() if ctx is None else ctx
        self._objects: list[Any] = []
        self._released = False
        try:
            self._setup(model)
        except BaseException:  # undo on any failure, Ctrl-C included; then re-raise
            self.release()
            raise

    # ----------------------------------------------------------------- construction
    def _track(self, obj: Any) -> Any:
        self._objects.append(obj)
        return obj

    def _buffer_texture(self, data: np.ndarray | int, fmt: str) -> BufferTexture:
        """A buffer texture of ``data`` (or of that many bytes, unset), owned by this object."""
        # The array itself (buffer protocol), not a bytes copy: 265 MB for 1080p's maps.
        content = np.ascontiguousarray(data) if isinstance(data, np.ndarray) else None
        reserve = int(data) if content is None else 0
        return self._track(BufferTexture(self.ctx, content, fmt, reserve, self._loader))

    def _tex(self, size: tuple[int, int], comps: int, dtype: str, data: Any = None) -> Any:
        tex = self._track(self.ctx.texture(size, comps, data, dtype=dtype, alignment=1))
        tex.filter = (moderngl.NEAREST, moderngl.NEAREST)  # reads at texel centres only
        tex.repeat_x = tex.repeat_y = True  # never used (centres lie inside); a bit cheaper
        return tex

    def _setup(self, model: RuntimeModel) -> None:
        if model.method not in _METHODS:
            raise ValueError(f"model.method must be one of {sorted(_METHODS)}, got {model.method}")
        if np.ndim(model.refl) != 3 or np.shape(model.refl)[2] != 3:
            raise ValueError(f"refl must be (H, W, 3), got {np.shape(model.refl)}")
        h, w = model.shape
        self.method: str = model.method
        self.height, self.width = h, w
        max_size = int(self.ctx.info["GL_MAX_TEXTURE_SIZE"])
        inv_lut = np.asarray(model.inv_lut)
        if inv_lut.ndim != 2 or inv_lut.shape[1] != 3:
            raise ValueError(f"inv_lut must be (N, 3), got {inv_lut.shape}")
        n_inv = int(inv_lut.shape[0])
        if max(w, h, n_inv) > max_size:
            raise ValueError(
                f"grid {w}x{h} / inverse LUT of {n_inv} entries exceeds GL_MAX_TEXTURE_SIZE "
                f"{max_size}"
            )
        if n_inv < 2:
            raise ValueError(f"inv_lut needs at least 2 entries, got {n_inv}")
        self._n_inv = n_inv
        self._programs: dict[tuple[Any, ...], tuple[Any, Any]] = {}
        self._input = 0
        self._color = self._track(self.ctx.renderbuffer((w, h), 4, dtype="f1"))
        self.fbo = self._track(self.ctx.framebuffer(color_attachments=[self._color]))

        self._rgb = self._tex((w, h), 3, "u1")
        self._y = self._tex((w, h), 1, "u1")
        cw, ch = (w + 1) // 2, (h + 1) // 2
        self._uv = self._tex((cw, ch), 2, "u1")
        self._uv_host = np.empty((ch, cw, 2), np.uint8)
        fwd = as_f32(model.fwd_lut, (256, 3), "fwd_lut")
        levels = np.broadcast_to(np.arange(256, dtype=np.float32)[:, None], (256, 3))
        fwd_rows = np.ascontiguousarray(lut_forward(fwd, levels).T)  # exact at integer levels
        self._fwd = self._buffer_texture(fwd_rows, "r32f")
        self._inv = self._buffer_texture(inv_pairs(inv_lut, n_inv), "rg32f")
        units: dict[str, Any] = {
            "u_rgb": self._rgb, "u_y": self._y, "u_uv": self._uv,
            "u_fwd": self._fwd, "u_inv": self._inv,
        }  # fmt: skip
        # Compiled-in constants (#define NAME literal) of every variant of this object.
        self._consts: dict[str, str | int] = {
            "GRID_W": w, "GRID_H": h, "N_INV": n_inv, "MAX_VIEWERS": MAX_VIEWERS,
        }  # fmt: skip
        self._cam_eye = as_f32(model.cam_eye, (3,), "cam_eye")
        self._inv_lo = as_f32(model.inv_lo, (3,), "inv_lo").astype(np.float64)
        self._inv_hi = as_f32(model.inv_hi, (3,), "inv_hi").astype(np.float64)
        if model.method == "pixel":
            units.update(self._upload_pixel_maps(model))
            lobe = lobe_table(model)
            units["u_lobe"] = self._buffer_texture(lobe, "rgba32f")
            self._consts["LOBE_N"] = int(lobe.shape[0])
            self._consts["LOBE_HALF"] = "true" if model.lobe_half else "false"
            self._consts["LOBE_BLACK"] = vec_literal(as_f32(model.lobe_black, (3,), "lobe_black"))
            sq = inverse_position(self._inv_lo, self._inv_hi, n_inv)
            self._consts.update({f"SQ_{k.upper()}": vec_literal(v) for k, v in sq.items()})
        if model.method == "paper":
            self._Ww = as_f32(model.Ww, (3, 3), "Ww").astype(np.float64)
            if model.Wc_inv is None:
                raise ValueError("paper method needs model.Wc_inv (3, 3)")
            self._Wc_inv = as_f32(model.Wc_inv, (3, 3), "Wc_inv").astype(np.float64)
        self._units = [(i, units.get(name)) for i, name in enumerate(_SAMPLERS)]
        self._view: tuple[Any, Any] | None = None  # (texture, framebuffer), made on first use
        self._view_eye: tuple[float, ...] | None = None  # the view the view cache holds
        self._last_eye: tuple[float, ...] | None = None
        self._held = 0  # draws in a row with the same eye, after the first
        self._building: tuple[float, ...] | None = None  # the eye of a cache under way
        self._band_row = 0  # its next grid row
        self.last_path = ""  # how the last draw ran: identity, solve, cached, audience or paper
        self.audience: Audience | None = None  # several viewers (set_audience), or one eye
        self.identity = False
        self.set_eye(*self._cam_eye)
        self.set_tone(1.0, 0.0)
        self._yuv_key: tuple[str, str] = ("bt709", "limited")

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
        key = (method, inp, yuv)
        if key not in self._programs:
            defines: dict[str, str | int | float] = {**self._consts, "METHOD": method, "INPUT": inp}
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

    def _frame_values(self) -> bytes:
        """The per-frame inputs v_frame[4] (vec4 each) of the current variant, as bytes."""
        out = np.zeros((4, 4), np.float32)
        if self._identity:
            pass
        elif self.method == "pixel":  # shader METHODs 1, 3 and 4 alike
            out[0, :3] = self.eye
            out[0, 3] = self.alpha
            out[1, 0] = self.beta
        elif self.method == "paper":
            out[:3] = paper_rows(self._Ww, self._Wc_inv, self._inv_lo, self._inv_hi,
                                 self._n_inv, self.alpha, self.beta)  # fmt: skip
        return out.tobytes()

    def _audience_values(self) -> bytes:
        """The audience as the shader's u_eyes[MAX_VIEWERS]: (eye.xyz, weight) per viewer."""
        out = np.zeros((MAX_VIEWERS, 4), np.float32)
        if self.audience is not None:
            k = len(self.audience)
            out[:k, :3] = self.audience.eyes
            out[:k, 3] = self.audience.weights
        return out.tobytes()

    def _shader_method(self) -> int:
        """The shader METHOD for the next draw; advances the view cache when it is due.

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
        fbo.read_into(view.buffer, viewport=band, components=4, dtype="f4",
                      write_offset=row_bytes * by * r0)  # fmt: skip
        self._band_row = r1
        if r1 < self.height:
            return False
        self._view_eye, self._building = eye, None
        return True

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

    # ----------------------------------------------------------------- state
    @property
    def identity(self) -> bool:
        """True: pass the frame through (same upload, shader and read-back), no compensation."""
        return self._identity

    @identity.setter
    def identity(self, on: bool) -> None:
        self._identity = bool(on)

    def set_eye(self, x: float, y: float, z: float) -> None:
        """Eye position in metres (world frame of docs/MODEL.md); one viewer from now on."""
        eye = np.array([x, y, z], np.float32)
        if not np.all(np.isfinite(eye)):
            raise ValueError(f"the eye must be three finite numbers, got {(x, y, z)}")
        self.eye = eye
        self.audience = None

    def set_audience(self, audience: Audience | np.ndarray) -> None:
        """Several viewers at once (pixel method; docs/MODEL.md section 6): an
        :class:`~viewcomp.calib.world.audience.Audience`, or eyes (K, 3) of equal weights.

        One viewer is :meth:`set_eye` of that eye: the same program and numbers, so the
        output is the same bit for bit. ``eye`` becomes the audience's weighted mean eye.
        """
        aud = Audience.of(audience)
        if len(aud) == 1:
            self.set_eye(*aud.eyes[0])
            return
        if self.method != "pixel":
            raise ValueError(f"an audience of several viewers needs the pixel method, not "
                             f"{self.method}")  # fmt: skip
        eye = np.asarray(aud.centre, np.float32)
        self.eye = eye
        self.audience = Audience(aud.eyes.astype(np.float32).astype(np.float64),
                                 aud.weights.astype(np.float32).astype(np.float64))  # fmt: skip

    def set_angle(self, deg: float, distance: float, height: float) -> None:
        """Eye from a viewing angle: E = (d cos t, h, d sin t); degrees and metres."""
        self.set_eye(*eye_from_angle(deg, distance, height))

    def set_tone(self, alpha: float, beta: float) -> None:
        """Tone map T = alpha * C_w + beta (Eq. 21), linear camera units."""
        if not (math.isfinite(alpha) and math.isfinite(beta)):
            raise ValueError(f"alpha and beta must be finite, got {alpha}, {beta}")
        self.alpha, self.beta = float(alpha), float(beta)

    def update_model(
        self,
        Wc_inv: np.ndarray | None = None,
        inv_lut: np.ndarray | None = None,
        inv_lo: np.ndarray | None = None,
        inv_hi: np.ndarray | None = None,
    ) -> None:
        """Per-eye updates (paper method): (W~_c)^-1 (3, 3) and rho_c^-1 (N, 3) on [lo, hi].

        Small uploads into the existing objects; ``inv_lut`` must keep its N entries. The
        pixel method's LUT domain is compiled in: it takes ``inv_lut`` only.
        """
        if self.method == "pixel" and (inv_lo is not None or inv_hi is not None):
            raise ValueError("the pixel method's inverse LUT domain is fixed: make a new one")
        if Wc_inv is not None:
            self._Wc_inv = as_f32(Wc_inv, (3, 3), "Wc_inv").astype(np.float64)
        if inv_lut is not None:
            self._inv.write(inv_pairs(inv_lut, self._n_inv))
        if inv_lo is not None:
            self._inv_lo = as_f32(inv_lo, (3,), "inv_lo").astype(np.float64)
        if inv_hi is not None:
            self._inv_hi = as_f32(inv_hi, (3,), "inv_hi").astype(np.float64)

    # ----------------------------------------------------------------- per frame
    def upload(self, frame: np.ndarray) -> None:
        """Upload an RGB frame (H, W, 3) uint8 (levels 0..255) as the next input."""
        if frame.shape != (self.height, self.width, 3) or frame.dtype != np.uint8:
            raise ValueError(
                f"frame must be uint8 {(self.height, self.width, 3)}, got {frame.dtype} "
                f"{frame.shape} (scale with viewcomp.rt.media.frames.fit_rgb first)"
            )
        self._rgb.write(np.ascontiguousarray(frame))
        self._input = 0

    def upload_planes(self, planes: Planes) -> None:
        """Upload a yuv420p frame (converted to RGB levels in the shader, see yuv.glsl)."""
        planes.check()
        if planes.shape != (self.height, self.width):
            raise ValueError(
                f"planes must be {(self.height, self.width)}, got {planes.shape} "
                "(the video reader fits frames to the grid)"
            )
        yuv_coefficients(planes.colorspace, planes.color_range)  # validates both
        self._y.write(np.ascontiguousarray(planes.y))
        self._uv_host[..., 0] = planes.u  # interleave: one chroma texture, half the reads
        self._uv_host[..., 1] = planes.v
        self._uv.write(self._uv_host)
        self._yuv_key = (planes.colorspace, planes.color_range)
        self._input = 1

    def upload_buffer(self, buffer: moderngl.Buffer) -> None:
        """Upload an RGB frame already on the GPU: a pixel buffer of this context holding
        (H, W, 3) uint8 levels in :meth:`upload`'s order (a copy within the driver)."""
        if buffer.size < self.width * self.height * 3:
            raise ValueError(f"the buffer holds {buffer.size} bytes, a frame needs "
                             f"{self.width * self.height * 3}")  # fmt: skip
        self._rgb.write(buffer, alignment=1)
        self._input = 0

    def draw(self) -> None:
        """Run the shader on the last upload into the own framebuffer.

        Returns at once: the draw is flushed to the driver, which renders on its own threads
        (llvmpipe) while the caller does other work; :meth:`read` waits for it.
        """
        self._draw(self.fbo, (0, 0, self.width, self.height), flip_y=0)
        flush(self.ctx)

    def read(self, out: np.ndarray | None = None) -> np.ndarray:
        """Read back the last draw as (H, W, 3) uint8 (into ``out`` if given, no copy).

        Waits for the draw with the GIL released (:func:`viewcomp.rt.gl.context.finish`), so
        other Python threads (decoder, encoder) run meanwhile.
        """
        shape = (self.height, self.width, 3)
        if out is None:
            out = np.empty(shape, np.uint8)
        elif out.shape != shape or out.dtype != np.uint8 or not out.flags.c_contiguous:
            raise ValueError(f"out must be a C-contiguous uint8 array {shape}, got {out.shape}")
        finish(self.ctx)
        self.fbo.read_into(out, components=3, alignment=1)
        return out

    def render(self, frame: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Compensate one RGB frame (H, W, 3) uint8 -> (H, W, 3) uint8 for the projector."""
        self.upload(frame)
        self.draw()
        return self.read(out)

    def render_planes(
        self,
        y: np.ndarray | Planes,
        u: np.ndarray | None = None,
        v: np.ndarray | None = None,
        colorspace: str = "bt709",
        color_range: str = "limited",
        out: np.ndarray | None = None,
    ) -> np.ndarray:
        """Compensate one yuv420p frame (planes, or a :class:`Planes`) -> (H, W, 3) uint8."""
        planes = y if isinstance(y, Planes) else Planes(y, u, v, colorspace, color_range)  # type: ignore[arg-type]
        self.upload_planes(planes)
        self.draw()
        return self.read(out)

    def render_to(
        self,
        framebuffer: moderngl.Framebuffer,
        origin: tuple[int, int] = (0, 0),
        flip_y: bool = True,
    ) -> None:
        """Draw the last upload into a host-owned framebuffer of the same context.

        Args:
            framebuffer: e.g. ``ctx.screen`` of a window (8-bit unorm colour).
            origin: window pixel (x, y) from the bottom-left where the grid's corner goes.
            flip_y: True for a window (y = 0 at the bottom), so array row 0 shows at the top.
        """
        viewport = (origin[0], origin[1], self.width, self.height)
        self._draw(framebuffer, viewport, flip_y=1 if flip_y else 0)

    # ----------------------------------------------------------------- lifetime
    def live_objects(self) -> int:
        """How many of the GL objects this compensator made are still alive (0 after release)."""
        return sum(1 for o in self._objects if not isinstance(o.mglo, moderngl.InvalidObject))

    def release(self) -> None:
        """Release every GL object (and the context if this object created it). Idempotent.

        If the context's current framebuffer (moderngl's ``ctx.fbo``) is one of this
        object's, the default framebuffer is bound first: moderngl re-binds its current
        framebuffer after making a new one, and a deleted name there is a GL error.
        """
        current = getattr(self.ctx, "fbo", None) if not self._released else None
        if current is not None and any(current is o for o in self._objects):
            (self.ctx.screen or self.ctx.detect_framebuffer(0)).use()
        for obj in reversed(self._objects):  # each release() is idempotent
            obj.release()
        if self._own_ctx and not self._released:
            self.ctx.release()
        self._released = True

    def __enter__(self) -> Compensator:
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()
