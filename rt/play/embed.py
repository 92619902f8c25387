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
from viewcomp.rt.gl.compensator import Compensator
from viewcomp.rt.gl.context import ProcAddress, default_proc_address, gl_function
from viewcomp.rt.media.frames import Planes, fit_rgb, thumbnail_planes
from viewcomp.rt.play.live import Command, EyeState, SetAngle, SetEye, check_angle, check_eye
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

    ``tone_eye`` is the eye the FrameParams were computed for (the tone map and, for the
    paper's method, the model); with ``async_tone`` it can lag ``eye`` by a few frames.
    """

    eye: np.ndarray
    params: FrameParams
    time: float
    tone_eye: np.ndarray
    identity: bool


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
        self._request: tuple[np.ndarray, np.ndarray, float] | None = None
        self._result: tuple[FrameParams, np.ndarray] | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="viewcomp-tone", daemon=True)
        self._thread.start()

    def compute(self, thumb: np.ndarray, eye: np.ndarray, t: float) -> FrameParams:
        """One synchronous call; also becomes the latest result."""
        start = time.perf_counter()
        with self._lock:
            p = self.comp(thumb, eye, t)
            self._result = (p, np.array(eye, np.float64))
            self.calls += 1
            self.busy_seconds += time.perf_counter() - start
        return p

    def submit(self, thumb: np.ndarray, eye: np.ndarray, t: float) -> None:
        """Ask for a call with these inputs (replaces a request not yet started)."""
        with self._cond:
            self._request = (thumb, np.array(eye, np.float64), t)
            self._cond.notify()

    def latest(self) -> tuple[FrameParams, np.ndarray] | None:
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
        self.compensator = Compensator(
            self._model, ctx, view_hold=8, view_steps=4, gl_loader=self._proc
        )
        h, w = self.compensator.height, self.compensator.width
        self.grid: tuple[int, int] = (w, h)
        self._tone = ToneWorker(self.comp, 1.0 / tone_hz) if async_tone else None
        self._released = False
        self.last: FrameRecord | None = None

    # ------------------------------------------------------------------ the eye
    def set_angle(self, degrees: float, smooth: bool = True) -> None:
        """Move to a viewing angle (degrees, [1, 179]) at the rig's viewer distance/height."""
        self.apply(SetAngle(check_angle(degrees)), smooth)

    def set_eye(self, x: float, y: float, z: float, smooth: bool = True) -> None:
        """Move to an eye position (metres; z >= 0.05, each within 50 m)."""
        self.apply(SetEye(check_eye((x, y, z))), smooth)

    def apply(self, command: Command, smooth: bool = True) -> None:
        """Apply a validated command from :mod:`viewcomp.rt.play.live`; ``smooth=False`` jumps."""
        self.eye_state.apply(command)
        if not smooth:
            self.eye_state.jump()

    @property
    def eye(self) -> np.ndarray:
        """The current (smoothed) eye (3,) metres."""
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

    def _params(
        self, thumb: np.ndarray, eye: np.ndarray, now: float
    ) -> tuple[FrameParams, np.ndarray]:
        if self._tone is None:
            return self.comp(thumb, eye, now), eye.copy()
        latest = self._tone.latest()
        if latest is None:  # the first frame: compute it here, once
            return self._tone.compute(thumb, eye, now), eye.copy()
        self._tone.submit(thumb, eye, now)
        return latest

    def prepare(self, frame: np.ndarray | Planes, now: float | None = None) -> FrameRecord:
        """Upload a frame and set eye, tone map and model for it; nothing is drawn yet."""
        now = time.monotonic() if now is None else now
        eye = self.eye_state.update(now).copy()
        if not isinstance(frame, Planes):
            w, h = self.grid
            frame = fit_rgb(np.asarray(frame, np.uint8), w, h)
        params, tone_eye = self._params(self._thumb(frame), eye, now)
        if params.model is not self._model:
            m = params.model
            if m.method == "paper":
                self.compensator.update_model(m.Wc_inv, m.inv_lut, m.inv_lo, m.inv_hi)
            self._model = m
        self.compensator.set_eye(*eye)
        self.compensator.set_tone(params.alpha, params.beta)
        if isinstance(frame, Planes):
            self.compensator.upload_planes(frame)
        else:
            self.compensator.upload(frame)
        self.last = FrameRecord(eye, params, now, tone_eye, self.identity)
        return self.last

    def draw(
        self,
        target: moderngl.Framebuffer,
        viewport: tuple[int, int, int, int] | None = None,
        size: tuple[int, int] | None = None,
        clear: bool = True,
    ) -> None:
        """Draw the prepared frame into ``target`` at ``viewport`` (x, y, w, h; GL window
        coordinates, origin bottom-left; default: the grid fitted into the target).

        ``size`` is the target's (W, H) (default ``target.size``; a window's default
        framebuffer may have been resized since the context was made). At the grid's size
        the shader writes the viewport directly; at any other size it renders the grid
        off-screen and scales it with a blit (``scale`` filter). With ``clear`` the rest of
        the target is cleared to black first (letterbox).
        """
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
        """:meth:`prepare` then :meth:`draw` (target default: ``ctx.screen``)."""
        record = self.prepare(frame, now)
        self.draw(self.ctx.screen if target is None else target, viewport)
        return record

    def warm_up(self, planes: bool = True, present: bool = False) -> None:
        """Compile the shader variant for yuv420p ``planes`` (else RGB) input, and the
        presentation pass with ``present``, by drawing a black frame off-screen once, so the
        first real frame is not late. The tone map is not touched."""
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
