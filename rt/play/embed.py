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
frame computes it synchronously. Cuts are detected here on every frame
(:class:`~viewcomp.calib.comp.shots.ShotDetector`, the rule ``render`` uses) and told to the
worker, which starts the new shot's search at once.

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

import time
from typing import TYPE_CHECKING, Any

import numpy as np

from viewcomp.calib.comp.compensation import Compensation, FrameParams, thumbnail
from viewcomp.calib.comp.shots import ShotDetector
from viewcomp.calib.comp.tonemap import DEFAULT_LAMBDA
from viewcomp.calib.model.reference import View
from viewcomp.calib.world.audience import Audience
from viewcomp.rt.gl.compensator import Compensator
from viewcomp.rt.gl.context import ProcAddress, default_proc_address
from viewcomp.rt.gl.state_guard import GLStateGuard, RawGL
from viewcomp.rt.media.frames import Planes, fit_rgb, thumbnail_planes
from viewcomp.rt.play.embed_present import (
    Presentation,
    ScaleFilter,
    fit_viewport,
    moderngl_filter,
)
from viewcomp.rt.play.embed_texture import TextureInput
from viewcomp.rt.play.frame_record import FrameRecord
from viewcomp.rt.play.live import (
    EyeCommand,
    EyeState,
    SetAngle,
    SetAudience,
    SetEye,
    check_angle,
    check_eye,
)
from viewcomp.rt.play.tone_worker import ToneWorker, copy_view

__all__ = [
    "FrameRecord", "GLStateGuard", "LiveRenderer", "ScaleFilter", "ToneWorker", "fit_viewport",
    "moderngl_filter",
]  # fmt: skip

if TYPE_CHECKING:
    import moderngl

    from viewcomp.calib.fit.calibrate import Calibration


class LiveRenderer(Presentation, TextureInput):
    """Compensated frames with a live, smoothed eye, drawn into a host's framebuffer.

    Args:
        cal: the calibration.
        ctx: the host's moderngl context (>= 3.3), current on this thread.
        method: ``"pixel"`` (default) or ``"paper"``.
        lam: the tone map's lambda (Eq. 22).
        tone: how the tone map is chosen (``Compensation``'s ``tone``): ``"paper"`` (Eq.
            21/22), ``"global"`` (one alpha, beta; the pixel method's default) or
            ``"adaptive"`` (the smooth gain/offset field with the hue-keeping soft clip,
            chosen per shot on the tone worker; pixel method, one eye); None: the method's.
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
        tone: str | None = None,
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
        self.comp = Compensation(cal, method, lam, tau=tone_tau or None, tone=tone)
        self.eye_state = EyeState(v.distance, height, start, eye_tau)
        self.audience: Audience | None = None  # several viewers, or None: the smoothed eye
        self.tone_side = int(tone_side)
        self.scale = scale
        # One GL loader (the host's; glfw's when a glfw context is current) for the raw calls
        # here and the Compensator's buffer textures.
        self._proc = proc_address or default_proc_address()
        self._raw: RawGL | None = None
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
        self._shots = ShotDetector()  # cuts seen on every frame, told to the tone worker
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
            x, y, z = (float(c) for c in aud.eyes[0])
            self.set_eye(x, y, z, smooth=smooth)
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
        cut = self._shots.is_cut(thumb)
        if self._tone is None:
            return self.comp(thumb, eye, now, cut), copy_view(eye)
        latest = self._tone.latest()
        if latest is None:  # the first frame: compute it here, once
            return self._tone.compute(thumb, eye, now, cut), copy_view(eye)
        self._tone.submit(thumb, eye, now, cut)
        return latest

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
        self.compensator.set_field(params.field)  # the adaptive map's (None: alpha, beta)
        if isinstance(frame, Planes):
            self.compensator.upload_planes(frame)
        elif frame is not None:
            self.compensator.upload(frame)
        self.last = FrameRecord(eye, params, now, tone_eye, self.identity, aud)
        return self.last

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
