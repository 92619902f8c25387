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
        comp.set_tone(alpha, beta)                # or comp.set_field(field): adaptive
        out = comp.render(frame)              # (H, W, 3) uint8 -> (H, W, 3) uint8

Threading: call it from the thread whose GL context is current (the thread that made it).
"""

from __future__ import annotations

import math
from typing import Any

import moderngl
import numpy as np

from viewcomp.calib.model.gamut import ToneField
from viewcomp.calib.model.reference import lut_forward
from viewcomp.calib.model.runtime import RuntimeModel
from viewcomp.calib.model.shader_inputs import (  # noqa: F401 (pixel_texels etc. re-exported)
    MAP_TEXELS,
    as_f32,
    inv_pairs,
    inverse_position,
    inverse_scale,
    lobe_table,
    luma_rows,
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
    flush,
)
from viewcomp.rt.gl.frame_io import FrameIO
from viewcomp.rt.gl.shader_passes import (
    _CACHED,  # noqa: F401 (the cached METHOD, for tests)
    _METHODS,
    _SAMPLERS,
    ShaderPasses,
)
from viewcomp.rt.gl.view_cache import ViewCache
from viewcomp.rt.media.frames import Planes
from viewcomp.shaders import vec_literal


class Compensator(FrameIO, ShaderPasses, ViewCache):
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
            units["u_luma"] = self._buffer_texture(luma_rows(model), "rgba32f")
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
        self.field: ToneField | None = None  # the adaptive tone map (set_field), or (alpha, beta)
        self.set_eye(*self._cam_eye)
        self.set_tone(1.0, 0.0)
        self._yuv_key: tuple[str, str] = ("bt709", "limited")

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
            raise ValueError(
                f"an audience of several viewers needs the pixel method, not {self.method}"
            )
        eye = np.asarray(aud.centre, np.float32)
        self.eye = eye
        self.audience = Audience(
            aud.eyes.astype(np.float32).astype(np.float64),
            aud.weights.astype(np.float32).astype(np.float64),
        )

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
    def draw(self) -> None:
        """Run the shader on the last upload into the own framebuffer.

        Returns at once: the draw is flushed to the driver, which renders on its own threads
        (llvmpipe) while the caller does other work; :meth:`read` waits for it.
        """
        self._draw(self.fbo, (0, 0, self.width, self.height), flip_y=0)
        flush(self.ctx)

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
