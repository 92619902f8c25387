"""The emulated camera (the :class:`~viewcomp.calib.hw.interface.Camera` protocol).

Timing on the shared :class:`~viewcomp.calib.emu.clock.VirtualClock`:

- a free-running camera (``profile.triggered`` False: the webcam) streams from the moment it
  is opened: frame k starts when frame k - 1 started plus max(frame interval, exposure); its
  rows start ``readout`` / (Hc - 1) apart (rolling shutter) and it is ready when its last row
  is exposed. Ready frames wait in the driver's queue of ``profile.queue`` buffers; when the
  queue is full, newer frames are dropped (a gap in the sequence). :meth:`EmulatedCamera.grab`
  returns the *oldest* queued frame, waiting (the clock advances) when none is ready. So a
  grab right after a pattern change returns frames exposed before it;
- a triggered camera (DSLR, machine vision) starts an exposure at the grab and returns when
  it is read out: the clock advances by the exposure plus ``profile.frame_interval``; all
  rows share one window (global shutter).

Frames are rendered when delivered, from the projector's timeline
(:meth:`~viewcomp.calib.emu.projector.EmulatedProjector.segments`), with the settings, screen
and pose they were exposed with.

Automatic modes (webcam): auto exposure meters the scene at each frame start and moves the
exposure toward a mid-grey target with a random hunting wobble, so it drifts while on; auto
white balance moves the channel gains toward the grey world of the scene, with a wobble. Both
stop when switched off (``auto_exposure`` / ``auto_white_balance`` = 0) and keep the values
they had; ``white_balance`` (kelvin) then sets the gains.
"""

from __future__ import annotations

import math
from collections import OrderedDict, deque
from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np

from viewcomp.calib.emu.clock import VirtualClock
from viewcomp.calib.emu.faults import Faults
from viewcomp.calib.emu.profiles import CameraProfile
from viewcomp.calib.emu.projector import EmulatedProjector
from viewcomp.calib.emu.scene import SceneView
from viewcomp.calib.hw.interface import ControlRange, DeviceError, Frame, FrameError
from viewcomp.calib.sim.simulator import AnyScreen
from viewcomp.calib.world.response import parse_response

#: Auto exposure's target: mean relative signal of the frame's centre half.
AE_TARGET = 0.12
#: Auto exposure's and white balance's hunting: log-normal wobble per frame.
AE_WOBBLE = 0.04
AWB_WOBBLE = 0.01
#: Weights of a mono sensor over the camera channels.
MONO_WEIGHTS = np.array([0.3, 0.5, 0.2], np.float32)
#: Noise-free signals (per window and pattern) a camera keeps.
SIGNAL_CACHE = 8


def kelvin_gains(kelvin: float) -> np.ndarray:
    """White balance gains (R, G, B) for a colour temperature (K): warmer light (lower K)
    gets less red and more blue gain; 5000 K is neutral."""
    r = (kelvin / 5000.0) ** 0.6
    return np.array([r, 1.0, 1.0 / r], np.float32)


def tone_curve(linear: np.ndarray, s: float) -> np.ndarray:
    """A webcam's tone response: the sRGB curve followed by an S-curve of strength ``s``
    (0..1: a blend with smoothstep), 0..1 -> 0..1."""
    enc = parse_response("srgb").encode(linear)
    return (1.0 - s) * enc + s * enc * enc * (3.0 - 2.0 * enc)


@dataclass
class _Exposure:
    """One frame as it was exposed (rendered later, when delivered)."""

    sequence: int
    start: float
    exposure: float
    gain: float
    wb: np.ndarray
    readout: float
    screen: str

    @property
    def ready(self) -> float:
        return self.start + self.readout + self.exposure


class EmulatedCamera:
    """A camera of ``profile`` looking at ``projector``'s light on the screen
    ``screens[screen_name()]``.

    ``scenes``: the scene as the camera sees it normally and, when a bump is injected, after
    it (:class:`SceneView`, one per pose). ``mixing`` (3, 3) the projector's primaries in
    camera channels. ``seed`` makes the noise and the automatic modes reproducible.
    """

    def __init__(
        self,
        clock: VirtualClock,
        projector: EmulatedProjector,
        profile: CameraProfile,
        scenes: tuple[SceneView, SceneView | None],
        screens: dict[str, AnyScreen],
        screen_name: Callable[[], str],
        seed: int = 0,
        faults: Faults | None = None,
    ) -> None:
        self.clock = clock
        self.projector = projector
        self.profile = profile
        self.scenes = scenes
        self.screens = screens
        self._screen_name = screen_name
        self.seed = int(seed)
        self.faults = faults or Faults()
        self._rng = np.random.default_rng([self.seed, 0xCA])
        self._fault_rng = np.random.default_rng([self.seed, 0xFA])
        self._closed = False
        p = profile
        self._values = {"exposure": snap(p.nominal_exposure, p.exposure), "gain": 1.0}
        self._auto_e = p.auto
        self._auto_wb = p.auto and p.white_balance is not None
        if p.white_balance is not None:
            self._values["white_balance"] = 5000.0
        self._wb = kelvin_gains(4000.0) if self._auto_wb else np.ones(3, np.float32)
        self._sequence = 0
        self._grabs = 0
        self._next_start = clock.now()
        self._pending: list[_Exposure] = []
        self._queue: deque[_Exposure] = deque()
        self._signals: OrderedDict[tuple[object, ...], np.ndarray] = OrderedDict()
        self._meter_cache: dict[int, np.ndarray] = {}
        #: Grab indices that raised FrameError, and sequence numbers lost (dropped).
        self.failed: list[int] = []
        self.dropped: list[int] = []

    # -- the protocol ----------------------------------------------------------------------

    @property
    def name(self) -> str:
        """What the device is."""
        return f"emulated {self.profile.name}"

    @property
    def resolution(self) -> tuple[int, int]:
        """(width, height) of the frames."""
        hc, wc = self.scenes[0].shape
        return (wc, hc)

    @property
    def channels(self) -> int:
        """3 (colour) or 1 (mono)."""
        return 3 if self.profile.bayer else 1

    def controls(self) -> dict[str, ControlRange]:
        """The controls this profile has, with their ranges."""
        p = self.profile
        out = {"exposure": p.exposure, "gain": p.gain}
        if p.white_balance is not None:
            out["white_balance"] = p.white_balance
        if p.auto:
            out["auto_exposure"] = ControlRange(0.0, 1.0, 1.0)
            if p.white_balance is not None:
                out["auto_white_balance"] = ControlRange(0.0, 1.0, 1.0)
        return out

    def get(self, control: str) -> float:
        """The control's value now."""
        self._check_open()
        self._range(control)
        self._advance(self.clock.now())
        if control == "auto_exposure":
            return float(self._auto_e)
        if control == "auto_white_balance":
            return float(self._auto_wb)
        return float(self._values[control])

    def set(self, control: str, value: float) -> float:
        """Ask for ``value``; returns what the device then reports (rounded to the control's
        step and clamped to its range; ignored while the control's automatic mode is on)."""
        self._check_open()
        rng = self._range(control)
        v = float(value)
        if not math.isfinite(v):
            raise DeviceError(f"{self.name}: {control} must be a finite number, got {value}")
        self._advance(self.clock.now())  # frames already started keep their settings
        v = snap(v, rng)
        if control == "auto_exposure":
            self._auto_e = bool(v)
        elif control == "auto_white_balance":
            self._auto_wb = bool(v)
            if not self._auto_wb:
                self._values["white_balance"] = self._values.get("white_balance", 5000.0)
        elif control == "exposure" and self._auto_e:
            pass  # the driver ignores a manual exposure while auto exposure is on
        elif control == "white_balance" and self._auto_wb:
            pass
        else:
            self._values[control] = v
            if control == "white_balance":
                self._wb = kelvin_gains(v)
        return self.get(control)

    def grab(self) -> Frame:
        """The next frame the driver delivers (see the module doc)."""
        self._check_open()
        g = self._grabs
        self._grabs += 1
        if self.profile.triggered:
            rec = self._shoot()
            if self.faults.drops(g, self._fault_rng):
                self.dropped.append(rec.sequence)
                rec = self._shoot()
        else:
            rec = self._dequeue()
            if self.faults.drops(g, self._fault_rng):
                self.dropped.append(rec.sequence)
                rec = self._dequeue()
        if self.faults.fails(g, self._fault_rng):
            self.failed.append(g)
            raise FrameError(f"{self.name}: the read of frame {rec.sequence} failed (grab {g})")
        return self._render(rec)

    def close(self) -> None:
        """Release the device (further calls raise DeviceError)."""
        self._closed = True

    # -- controls ----------------------------------------------------------------------------

    def _check_open(self) -> None:
        if self._closed:
            raise DeviceError(f"{self.name} is closed")

    def _range(self, control: str) -> ControlRange:
        ctl = self.controls()
        if control not in ctl:
            raise DeviceError(
                f"{self.name} has no control {control!r}; it has {', '.join(sorted(ctl))}"
            )
        return ctl[control]

    # -- timing ------------------------------------------------------------------------------

    def _new_exposure(self, start: float) -> _Exposure:
        p = self.profile
        rec = _Exposure(
            sequence=self._sequence,
            start=start,
            exposure=self._values["exposure"],
            gain=self._values["gain"],
            wb=self._wb.copy(),
            readout=p.readout,
            screen=self._screen_name(),
        )
        self._sequence += 1
        self._auto(start)
        return rec

    def _advance(self, now: float) -> None:
        """Start every free-running frame due by ``now`` and queue those read out by then."""
        if self.profile.triggered:
            return
        while self._next_start <= now:
            rec = self._new_exposure(self._next_start)
            self._pending.append(rec)
            self._next_start += max(self.profile.frame_interval, rec.exposure)
        while self._pending and self._pending[0].ready <= now:
            rec = self._pending.pop(0)
            if len(self._queue) < self.profile.queue:
                self._queue.append(rec)
            else:
                self.dropped.append(rec.sequence)  # every buffer full: the driver drops it

    def _dequeue(self) -> _Exposure:
        """The oldest queued frame, waiting for one when the queue is empty."""
        self._advance(self.clock.now())
        while not self._queue:
            nxt = self._pending[0].ready if self._pending else self._next_start
            self.clock.advance_to(nxt)
            self._advance(self.clock.now())
        return self._queue.popleft()

    def _shoot(self) -> _Exposure:
        """A triggered exposure from now; the clock advances until it is read out."""
        rec = self._new_exposure(self.clock.now())
        self.clock.advance_to(rec.ready + self.profile.frame_interval)
        return rec

    # -- automatic exposure and white balance ----------------------------------------------

    def _meter(self, t: float) -> np.ndarray:
        """The scene's mean radiance (3,) at time ``t`` (what the camera's meter reads)."""
        shown = self.projector.shown_at(t)
        key = shown.index
        light = self._meter_cache.get(key)
        if light is None:
            light = self.projector.model.steady(shown.image).reshape(-1, 3).mean(axis=0)
            self._meter_cache = {key: light}
        scene = self.scenes[0]
        r_term, a_term = scene.terms(self.screens[self._screen_name()])
        hs, ws = r_term.shape[:2]
        centre = (slice(hs // 4, hs - hs // 4), slice(ws // 4, ws - ws // 4))  # centre-weighted
        mix = scene.mixing.astype(np.float64)
        r_mean = r_term[centre].reshape(-1, 3).mean(0)
        return r_mean * (mix @ light) + a_term[centre].reshape(-1, 3).mean(0)

    def _auto(self, t: float) -> None:
        """One step of the automatic modes that are on, at a frame start ``t``."""
        if not (self._auto_e or self._auto_wb):
            return
        m = self._meter(t)
        p = self.profile
        if self._auto_e:
            level = float(np.mean(m)) * p.sensitivity * self._values["exposure"]
            level *= self._values["gain"]
            ratio = (AE_TARGET / max(level, 1e-6)) ** 0.5
            e = self._values["exposure"] * ratio * math.exp(self._rng.normal(0.0, AE_WOBBLE))
            e = min(e, p.frame_interval)
            self._values["exposure"] = snap(e, p.exposure)
        if self._auto_wb:
            target = float(np.mean(m)) / np.maximum(m, 1e-9)
            target = (target / target[1]).astype(np.float32)
            wb = self._wb + 0.3 * (target - self._wb)
            wb *= np.exp(self._rng.normal(0.0, AWB_WOBBLE, 3)).astype(np.float32)
            self._wb = wb.astype(np.float32)

    # -- rendering ---------------------------------------------------------------------------

    def _signal(self, rec: _Exposure) -> np.ndarray:
        """The noise-free relative signal of a frame, before the sensor: (Hc, Wc, 3)."""
        bump = self.faults.bump_at
        scene = self.scenes[0]
        if bump is not None and self.scenes[1] is not None:
            t_bump = self.projector.swap_time(bump[0])
            if t_bump is not None and rec.start >= t_bump:
                scene = self.scenes[1]
        hc = scene.shape[0]
        if rec.readout > 0:
            t0 = rec.start + np.arange(hc) * (rec.readout / max(hc - 1, 1))
        else:
            t0 = np.array([rec.start])
        t1 = t0 + rec.exposure
        segs = self.projector.segments(float(t0[0]), float(t1[-1]))
        period = self.projector.model.period
        key = (
            id(scene),
            rec.screen,
            round(rec.exposure, 9),
            round(rec.readout, 9),
            round(math.fmod(rec.start, period), 9),
            tuple((s.index, round(a - rec.start, 9), round(b - rec.start, 9)) for a, b, s in segs),
        )
        got = self._signals.get(key)
        if got is not None:
            self._signals.move_to_end(key)
            return got
        pieces = []
        for a, b, s in segs:
            luts = self.projector.model.drive_luts(np.maximum(t0, a), np.minimum(t1, b))
            pieces.append((s.index, s.image, luts))
        integral = scene.integrate(self.screens[rec.screen], pieces, rec.exposure)
        sig = optics(
            np.asarray(integral * np.float32(self.profile.sensitivity), np.float32), self.profile
        )
        self._signals[key] = sig
        while len(self._signals) > SIGNAL_CACHE:
            self._signals.popitem(last=False)
        return sig

    def _render(self, rec: _Exposure) -> Frame:
        sig = self._signal(rec)
        oldest = min(
            [rec.start, *(r.start for r in self._queue), *(r.start for r in self._pending)]
        )
        self.projector.forget_before(oldest)
        return develop(sig, rec, self.profile, self.seed)


# -- the sensor and the image processing (signal -> frame) ------------------------------------


def optics(sig: np.ndarray, p: CameraProfile) -> np.ndarray:
    """The relative signal ``sig`` (Hc, Wc, 3) float32 as ``p``'s lens images it: blurred by
    ``blur_px`` (a Gaussian, edges reflected), float32."""
    if p.blur_px <= 0:
        return sig
    blurred = cv2.GaussianBlur(sig, (0, 0), p.blur_px, borderType=cv2.BORDER_REFLECT)
    return np.asarray(blurred, np.float32)


def develop_image(
    sig: np.ndarray, p: CameraProfile, gain: float, wb: np.ndarray, rng: np.random.Generator
) -> np.ndarray:
    """The image a camera of profile ``p`` delivers from the relative signal ``sig`` (Hc, Wc,
    3), after its optics: the sensor's codes at ``gain`` (:func:`sensor_codes`, noise from
    ``rng``), then raw (mono, (Hc, Wc) uint16), demosaiced (linear colour, (Hc, Wc, 3)
    uint16) or processed as a webcam does (:func:`webcam_process`, white balance gains ``wb``
    (3,): (Hc, Wc, 3) uint8 RGB)."""
    raw = sensor_codes(sig, p, gain, rng)
    if not p.bayer:
        return raw
    if p.linear:
        return cv2.cvtColor(raw, cv2.COLOR_BayerBG2RGB)  # bilinear; RGGB from row 0
    return webcam_process(raw, wb, p)


def develop(sig: np.ndarray, rec: _Exposure, p: CameraProfile, seed: int) -> Frame:
    """The frame a camera of profile ``p`` delivers from the noise-free relative signal
    ``sig`` (Hc, Wc, 3) of exposure ``rec`` (:func:`develop_image`, noise drawn from ``seed``
    and the frame's sequence number)."""
    rng = np.random.default_rng([seed, rec.sequence, 0x5E])
    image = develop_image(sig, p, rec.gain, rec.wb, rng)
    return Frame(
        image=image,
        timestamp=rec.start,
        exposure=rec.exposure,
        gain=rec.gain,
        sequence=rec.sequence,
        bits=p.out_bits,
        linear=p.linear,
    )


def sensor_codes(
    sig: np.ndarray, p: CameraProfile, gain: float, rng: np.random.Generator
) -> np.ndarray:
    """The sensor's raw codes (Hc, Wc) uint16 for the relative signal ``sig`` (Hc, Wc, 3):
    sampled through an RGGB Bayer mosaic (or mono weights), shot and read noise in electrons
    (from ``rng``), then ``gain`` and the ADC's ``p.raw_bits``."""
    if p.bayer:
        photo = np.empty(sig.shape[:2], np.float32)  # RGGB
        photo[0::2, 0::2] = sig[0::2, 0::2, 0]
        photo[0::2, 1::2] = sig[0::2, 1::2, 1]
        photo[1::2, 0::2] = sig[1::2, 0::2, 1]
        photo[1::2, 1::2] = sig[1::2, 1::2, 2]
    else:
        photo = sig @ MONO_WEIGHTS
    electrons = np.maximum(photo, 0.0) * np.float32(p.full_well)
    sd = np.sqrt(electrons + np.float32(p.read_noise**2))
    electrons = electrons + sd * rng.standard_normal(electrons.shape, np.float32)
    top = (1 << p.raw_bits) - 1
    raw = np.clip(np.rint(electrons * np.float32(gain * top / p.full_well)), 0, top)
    return raw.astype(np.uint16)


def webcam_process(raw: np.ndarray, wb: np.ndarray, p: CameraProfile) -> np.ndarray:
    """A webcam's image processing: demosaic, white balance (gains ``wb`` (3,)), tone curve,
    denoise, sharpen, 8 bits, MJPEG. (Hc, Wc) raw codes -> (Hc, Wc, 3) uint8 RGB."""
    rgb = cv2.cvtColor(raw, cv2.COLOR_BayerBG2RGB_EA).astype(np.float32)
    rgb *= wb / np.float32((1 << p.raw_bits) - 1)
    enc = tone_curve(np.clip(rgb, 0.0, 1.0), p.tone_s)
    if p.denoise > 0:
        enc = cv2.GaussianBlur(enc, (0, 0), p.denoise)
    if p.sharpen > 0:
        soft = cv2.GaussianBlur(enc, (0, 0), 1.0)
        enc = enc + np.float32(p.sharpen) * (enc - soft)
    out = np.clip(np.rint(enc * 255.0), 0, 255).astype(np.uint8)
    if p.mjpeg_quality > 0:
        out = mjpeg(out, p.mjpeg_quality)
    return out


def mjpeg(rgb: np.ndarray, quality: int) -> np.ndarray:
    """An MJPEG round trip: (H, W, 3) uint8 RGB encoded as JPEG at ``quality`` and decoded."""
    ok, buf = cv2.imencode(".jpg", rgb[:, :, ::-1], [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise DeviceError("the emulated webcam could not encode its frame as JPEG")
    decoded = cv2.imdecode(buf, cv2.IMREAD_COLOR)
    if decoded is None:
        raise DeviceError("the emulated webcam could not decode its own JPEG frame")
    return np.ascontiguousarray(decoded[:, :, ::-1])


def snap(value: float, rng: ControlRange) -> float:
    """``value`` clamped to ``rng`` and rounded to its step (counted from ``low``)."""
    v = min(max(value, rng.low), rng.high)
    if rng.step > 0:
        v = rng.low + round((v - rng.low) / rng.step) * rng.step
        v = min(max(v, rng.low), rng.high)
        digits = max(0, -math.floor(math.log10(rng.step)) + 3)
        v = round(v, digits)
    return float(v)
