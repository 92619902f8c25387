"""Compensation with a live eye into a host's framebuffer: the embedding API.

A host that owns its GL context (its own window, a game engine, a kiosk shell) makes one
:class:`LiveRenderer` for a calibration and, each frame, hands it the frame and where to
draw; it moves the eye whenever its tracker says so::

    import moderngl
    from viewcomp.calib.fit.calibrate import Calibration
    from viewcomp.rt.play.embed import LiveRenderer

    ctx = moderngl.create_context()               # the host's context, current here
    live = LiveRenderer(Calibration.load("screen.vcb"), ctx, angle=90.0)
    ...
    live.set_angle(tracker_angle)                 # or live.set_eye(x, y, z); smoothed
    record = live.render(frame_rgb, target=ctx.screen, viewport=(0, 0, w, h))
    ...                                           # swap buffers (the host's job)
    live.release()                                # every GL object it made

What it does per frame: the frame (RGB (h, w, 3) uint8 of any size, fitted to the grid, or
yuv420p :class:`~viewcomp.rt.media.frames.Planes` already on the grid) -> a thumbnail ->
``Compensation(cal, method, tau)(thumbnail, eye, now)`` -> (model, alpha, beta) -> the GL
:class:`~viewcomp.rt.gl.compensator.Compensator` at the projector grid's resolution -> the
target's viewport (drawn directly when the viewport is the grid's size, else scaled with a
framebuffer blit). The returned :class:`FrameRecord` says which eye and which
``FrameParams`` that frame used, so any frame can be checked against
``viewcomp.calib.model.reference.compensate``.

The tone map (and, for the paper's method, the model, which depends on the eye) costs
20-500 ms of CPU per call; with ``async_tone=True`` (default) it runs on a worker thread at
most ``tone_hz`` times a second and each frame uses the newest result: frames never wait for
it, and with the tone smoothing (``tone_tau``, 0.5 s) the lag does not show. The first
frame computes it synchronously.

A frame already in one of the host's GL textures goes in with :meth:`LiveRenderer.render_texture`
(the texture's id, size and format): it is fitted to the grid on the GPU and copied into the
compensator's input within the driver; only the grid-sized input is read back, and only when
the tone map takes a new thumbnail (at most ``tone_hz`` times a second).

The host's GL state (docs/PLAYER.md, "Embedding"): :meth:`LiveRenderer.render`,
:meth:`~LiveRenderer.render_texture`, :meth:`~LiveRenderer.prepare` and
:meth:`~LiveRenderer.draw` set every state their drawing depends on and restore what they
changed (:class:`GLStateGuard` lists it), and draw only into the viewport given.

Threading: construct, render and release on the thread where ``ctx`` is current. The eye
setters are cheap; call them from that thread too (the player queues its inputs there).
"""

from __future__ import annotations

import ctypes
import threading
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from viewcomp.calib.comp.compensation import Compensation, FrameParams, thumbnail
from viewcomp.calib.comp.tonemap import DEFAULT_LAMBDA
from viewcomp.calib.model.reference import View
from viewcomp.calib.world.audience import Audience
from viewcomp.rt.gl.compensator import Compensator
from viewcomp.rt.gl.context import ProcAddress, default_proc_address, gl_function
from viewcomp.rt.media.frames import Planes, fit_rect, fit_rgb, thumbnail_planes
from viewcomp.rt.play.live import (
    EyeCommand,
    EyeState,
    SetAngle,
    SetAudience,
    SetEye,
    check_angle,
    check_eye,
)
from viewcomp.shaders import build_program

if TYPE_CHECKING:
    import moderngl

    from viewcomp.calib.fit.calibrate import Calibration

ScaleFilter = Literal["auto", "linear", "nearest"]

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


class _GL:
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
        self._blit(sx, sy, sx + sw, sy + sh, dx, dy, dx + dw, dy + dh, _GL_COLOR_BUFFER_BIT,
                   _GL_LINEAR if linear else _GL_NEAREST)  # fmt: skip
        dst.use()  # moderngl's own binding again


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


@dataclass(frozen=True)
class FrameRecord:
    """What one rendered frame used: the eye (3,) metres, the FrameParams, the time (s).

    ``tone_eye`` is the eye (or audience) the FrameParams were computed for (the tone map
    and, for the paper's method, the model); with ``async_tone`` it can lag ``eye`` by a few
    frames. ``audience``: the viewers compensated for when there were several (``eye`` is
    then their weighted mean), else None.
    """

    eye: np.ndarray
    params: FrameParams
    time: float
    tone_eye: View
    identity: bool
    audience: Audience | None = None


def _copy_view(eye: View) -> View:
    """An eye as a float64 copy; an audience (immutable) as it is."""
    return eye if isinstance(eye, Audience) else np.array(eye, np.float64)


class ToneWorker:
    """``Compensation`` calls on a worker thread; the newest request wins.

    ``compute`` runs one call synchronously (under the same lock); ``submit`` hands a request
    to the thread; ``latest`` returns the newest result with the eye it was computed for.
    The thread keeps its duty cycle at or below one half: after a call of cost c it rests
    until max(period, 2 c) has passed since the call began.
    """

    def __init__(self, comp: Compensation, period: float = 0.1) -> None:
        self.comp = comp
        self.period = float(period)
        self.calls = 0
        self.busy_seconds = 0.0
        self._lock = threading.Lock()
        self._cond = threading.Condition()
        self._request: tuple[np.ndarray, View, float] | None = None
        self._result: tuple[FrameParams, View] | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="viewcomp-tone", daemon=True)
        self._thread.start()

    def compute(self, thumb: np.ndarray, eye: View, t: float) -> FrameParams:
        """One synchronous call; also becomes the latest result."""
        start = time.perf_counter()
        with self._lock:
            p = self.comp(thumb, eye, t)
            self._result = (p, _copy_view(eye))
            self.calls += 1
            self.busy_seconds += time.perf_counter() - start
        return p

    def submit(self, thumb: np.ndarray, eye: View, t: float) -> None:
        """Ask for a call with these inputs (replaces a request not yet started)."""
        with self._cond:
            self._request = (thumb, _copy_view(eye), t)
            self._cond.notify()

    def latest(self) -> tuple[FrameParams, View] | None:
        """The newest (FrameParams, eye) or None before the first call."""
        return self._result

    def _run(self) -> None:
        while not self._stop.is_set():
            with self._cond:
                while self._request is None and not self._stop.is_set():
                    self._cond.wait(0.1)
                req, self._request = self._request, None
            if req is None:
                continue
            start = time.perf_counter()
            try:
                self.compute(*req)
            except Exception:  # keep the last good parameters; the frame goes on
                import logging

                logging.getLogger(__name__).exception("tone map computation failed")
            cost = time.perf_counter() - start
            if self._stop.wait(max(self.period - cost, cost)):
                return

    def stop(self) -> None:
        """Stop the thread (a call in progress finishes first)."""
        self._stop.set()
        with self._cond:
            self._cond.notify_all()
        if self._thread.is_alive():
            self._thread.join(timeout=5.0)


class LiveRenderer:
    """Compensated frames with a live, smoothed eye, drawn into a host's framebuffer.

    Args:
        cal: the calibration.
        ctx: the host's moderngl context (>= 3.3), current on this thread.
        method: ``"pixel"`` (default) or ``"paper"``.
        lam: the tone map's lambda (Eq. 22).
        tone_tau: time constant (s) of the tone map's smoothing (None/0: none).
        eye_tau: time constant (s) of the eye's smoothing (0: moves are instant).
        angle: the start viewing angle (degrees) at the rig's viewer distance and height;
            ignored when ``eye`` is given.
        eye: the start eye (x, y, z) metres.
        audience: several viewers at once from the start (pixel method; docs/MODEL.md
            section 6); ``angle``/``eye`` then only say where a later single eye starts.
        async_tone: compute the tone map on a worker thread (see the module docstring).
        tone_hz: at most this many tone-map calls a second with ``async_tone``.
        tone_side: longest side (pixels) of the tone map's thumbnail.
        scale: the filter when the viewport is not the grid's size: ``"nearest"`` (each grid
            pixel a block), ``"linear"``, or ``"auto"``: nearest for whole-number scale
            factors (the projector's pixels, enlarged), else linear.
        proc_address: GL function loader (name -> address) for the scaling blit; None:
            :func:`default_proc_address`.

    Raises:
        ValueError: a bad method, angle or eye.
    """

    def __init__(
        self,
        cal: Calibration,
        ctx: moderngl.Context,
        *,
        method: str = "pixel",
        lam: float = DEFAULT_LAMBDA,
        tone_tau: float | None = 0.5,
        eye_tau: float = 0.25,
        angle: float = 90.0,
        eye: tuple[float, float, float] | None = None,
        audience: Audience | None = None,
        async_tone: bool = True,
        tone_hz: float = 5.0,
        tone_side: int = 32,
        scale: ScaleFilter = "auto",
        proc_address: ProcAddress | None = None,
    ) -> None:
        if scale not in ("auto", "linear", "nearest"):
            raise ValueError(f"scale must be 'auto', 'linear' or 'nearest', got {scale!r}")
        v = cal.rig.viewer
        height = float(v.height) if v.height is not None else 0.0
        start = check_eye(eye) if eye is not None else None
        if start is None:
            start = tuple(cal.eye(angle=check_angle(angle)).tolist())
        self.cal = cal
        self.ctx = ctx
        self.comp = Compensation(cal, method, lam, tau=tone_tau or None)
        self.eye_state = EyeState(v.distance, height, start, eye_tau)
        self.audience: Audience | None = None  # several viewers, or None: the smoothed eye
        self.tone_side = int(tone_side)
        self.scale = scale
        # One GL loader (the host's; glfw's when a glfw context is current) for the raw calls
        # here and the Compensator's buffer textures.
        self._proc = proc_address or default_proc_address()
        self._raw: _GL | None = None
        self._present: tuple[Any, Any, Any, Any] | None = None
        self._objects: list[Any] = []
        self._model = self.comp.base_model()
        # The view cache once the eye has rested a quarter second at 30 fps (a tracker's
        # jitter or the eye's easing must not start rebuilds), built over 4 frames.
        self._guard = GLStateGuard(ctx, self._proc)
        with self._guard:  # its uploads must not follow the host's pixel-store state
            self.compensator = Compensator(
                self._model, ctx, view_hold=8, view_steps=4, gl_loader=self._proc
            )
        h, w = self.compensator.height, self.compensator.width
        self.grid: tuple[int, int] = (w, h)
        self._tone = ToneWorker(self.comp, 1.0 / tone_hz) if async_tone else None
        self._tone_period = 1.0 / tone_hz
        self._tex_in: tuple[Any, Any, Any, Any] | None = None
        self._tex_thumb: tuple[np.ndarray, float] | None = None
        self._released = False
        self.last: FrameRecord | None = None
        if audience is not None:
            self.set_audience(audience, smooth=False)

    # ------------------------------------------------------------------ the eye
    def set_angle(self, degrees: float, smooth: bool = True) -> None:
        """Move to a viewing angle (degrees, [1, 179]) at the rig's viewer distance/height."""
        self.apply(SetAngle(check_angle(degrees)), smooth)

    def set_eye(self, x: float, y: float, z: float, smooth: bool = True) -> None:
        """Move to an eye position (metres; z >= 0.05, each within 50 m)."""
        self.apply(SetEye(check_eye((x, y, z))), smooth)

    def set_audience(self, audience: Audience | np.ndarray, smooth: bool = True) -> None:
        """Compensate for several viewers at once (an
        :class:`~viewcomp.calib.world.audience.Audience`, or eyes (K, 3) of equal weights;
        pixel method). One viewer is :meth:`set_eye` of that eye (smoothed like it); an
        audience takes effect at once (a tracker smooths its faces itself). A later eye or
        angle command ends it."""
        aud = Audience.of(audience)
        if len(aud) == 1:
            self.audience = None
            self.set_eye(*aud.eyes[0], smooth=smooth)
            return
        if self.comp.method != "pixel":
            raise ValueError("an audience of several viewers needs the pixel method")
        self.audience = aud

    def apply(self, command: EyeCommand, smooth: bool = True) -> None:
        """Apply a validated eye command from :mod:`viewcomp.rt.play.live` (``SetAngle``,
        ``SetAngleNorm``, ``SetEye``, ``NudgeAngle``, ``SetAudience``); ``smooth=False``
        jumps. The show control (pause, seek, ...) is the host's: a TypeError here."""
        if isinstance(command, SetAudience):
            if self.comp.method != "pixel":  # the paper's method: the nearest (first) face
                command = SetEye(command.eyes[0])
            else:
                self.set_audience(np.asarray(command.eyes, np.float64), smooth)
                return
        self.audience = None
        self.eye_state.apply(command)
        if not smooth:
            self.eye_state.jump()

    @property
    def eye(self) -> np.ndarray:
        """The current (smoothed) eye (3,) metres; for an audience its weighted mean eye."""
        if self.audience is not None:
            return self.audience.centre
        return self.eye_state.current.copy()

    @property
    def identity(self) -> bool:
        """True: compensation off (the same pipeline passes the frame through)."""
        return self.compensator.identity

    @identity.setter
    def identity(self, on: bool) -> None:
        self.compensator.identity = on

    # ------------------------------------------------------------------ per frame
    def _thumb(self, frame: np.ndarray | Planes) -> np.ndarray:
        if isinstance(frame, Planes):
            return thumbnail_planes(frame, self.tone_side)
        return thumbnail(frame, self.tone_side)

    def _params(self, thumb: np.ndarray, eye: View, now: float) -> tuple[FrameParams, View]:
        if self._tone is None:
            return self.comp(thumb, eye, now), _copy_view(eye)
        latest = self._tone.latest()
        if latest is None:  # the first frame: compute it here, once
            return self._tone.compute(thumb, eye, now), _copy_view(eye)
        self._tone.submit(thumb, eye, now)
        return latest

    @property
    def state_guard(self) -> GLStateGuard:
        """The guard that saves and restores the host's GL state around every call."""
        return self._guard

    def prepare(self, frame: np.ndarray | Planes, now: float | None = None) -> FrameRecord:
        """Upload a frame and set eye, tone map and model for it; nothing is drawn yet."""
        now = time.monotonic() if now is None else now
        if not isinstance(frame, Planes):
            w, h = self.grid
            frame = fit_rgb(np.asarray(frame, np.uint8), w, h)
        with self.state_guard:
            return self._set_frame(self._thumb(frame), now, frame)

    def _set_frame(
        self, thumb: np.ndarray, now: float, frame: np.ndarray | Planes | None
    ) -> FrameRecord:
        """Eye, tone map and model for a frame with this thumbnail; uploads ``frame`` (None:
        the input is already in place)."""
        eye = self.eye_state.update(now).copy()
        aud = self.audience
        params, tone_eye = self._params(thumb, eye if aud is None else aud, now)
        if params.model is not self._model:
            m = params.model
            if m.method == "paper":
                self.compensator.update_model(m.Wc_inv, m.inv_lut, m.inv_lo, m.inv_hi)
            self._model = m
        if aud is None:
            self.compensator.set_eye(*eye)
        else:
            self.compensator.set_audience(aud)
            eye = aud.centre
        self.compensator.set_tone(params.alpha, params.beta)
        if isinstance(frame, Planes):
            self.compensator.upload_planes(frame)
        elif frame is not None:
            self.compensator.upload(frame)
        self.last = FrameRecord(eye, params, now, tone_eye, self.identity, aud)
        return self.last

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

    def render(
        self,
        frame: np.ndarray | Planes,
        target: moderngl.Framebuffer | None = None,
        viewport: tuple[int, int, int, int] | None = None,
        now: float | None = None,
    ) -> FrameRecord:
        """:meth:`prepare` then :meth:`draw` (target default: ``ctx.screen``): only the
        viewport's pixels change, and the host's GL state is as it was afterwards."""
        with self.state_guard:
            record = self.prepare(frame, now)
            self.draw(self.ctx.screen if target is None else target, viewport)
        return record

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

    def _gl(self) -> _GL:
        if self._raw is None:
            self._raw = _GL(self._proc)
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

    # ------------------------------------------------------------------ lifetime
    def live_objects(self) -> int:
        """GL objects of this renderer (and its Compensator) still alive; 0 after release."""
        import moderngl

        mine = sum(1 for o in self._objects if not isinstance(o.mglo, moderngl.InvalidObject))
        return mine + self.compensator.live_objects()

    def release(self) -> None:
        """Stop the tone worker and release every GL object made here. Idempotent."""
        if self._released:
            return
        self._released = True
        if self._tone is not None:
            self._tone.stop()
        for obj in reversed(self._objects):
            obj.release()
        self.compensator.release()

    def __enter__(self) -> LiveRenderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()
