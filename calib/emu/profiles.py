"""The emulated cameras' profiles: what each kind of device does to the light.

Signal chain (:mod:`viewcomp.calib.emu.camera`): the scene integrated over each row's exposure
window, area-averaged over the camera's pixels, blurred by the optics, vignetted; then the
sensor (relative signal s = ``sensitivity`` * integral; electrons e = s * ``full_well``, shot
noise sqrt(e), ``read_noise`` electrons; codes = e * gain * (2^``raw_bits`` - 1) /
``full_well``, clipped), a Bayer mosaic and OpenCV's demosaicking for colour sensors, and for
a webcam its processing (white balance, tone curve, denoising, sharpening, 8 bits, MJPEG).

``sensitivity`` is chosen so that ``nominal_exposure`` seconds of light give the simulator's
exposure (0.8 of full scale for the radiance of a white Lambertian surface of albedo 1 under
the full projector at its centre): the emulated cameras see what the simulated one sees at
their nominal exposure.
"""

from __future__ import annotations

from dataclasses import dataclass

from viewcomp.calib.hw.interface import ControlRange

#: The simulator's exposure (CameraPhysics.exposure): relative signal per unit radiance at the
#: nominal exposure time.
SIM_EXPOSURE = 0.8


@dataclass(frozen=True)
class CameraProfile:
    """One kind of camera.

    Geometry: ``density`` camera pixels per projector pixel on the simulation rig's geometry
    (1.2 is the simulator's camera; the camera's resolution follows from it and the
    projector's), ``distortion`` (k1, k2, p1, p2, k3), ``blur_px`` optics sigma (camera px),
    ``vignetting`` exponent on the cos^4 fall-off (1: cos^4, 2: cos^8).
    Timing (seconds): ``frame_interval`` the shortest time between frame starts (free-running
    cameras) or the time per shot after the exposure (``triggered``), ``readout`` the time
    between the first and the last row's start (0: global shutter), ``queue`` driver buffers
    (0: each grab takes a new frame).
    Sensor: ``raw_bits``, ``full_well`` (e-), ``read_noise`` (e-), ``bayer`` colour mosaic or
    mono, ``nominal_exposure`` (s).
    Output: ``out_bits`` (8 or more), ``linear`` codes proportional to light or processed,
    ``mjpeg_quality`` (0: none), ``tone_s`` S-curve strength on top of sRGB (0..1),
    ``sharpen`` unsharp-mask amount, ``denoise`` Gaussian sigma (camera px; 0: none).
    Controls: their ranges (:data:`~viewcomp.calib.hw.interface.CONTROLS` units) and the
    automatic modes on at start (``auto`` exposure/white balance).
    """

    name: str
    density: float
    distortion: tuple[float, float, float, float, float]
    blur_px: float
    vignetting: float
    frame_interval: float
    readout: float
    queue: int
    triggered: bool
    raw_bits: int
    full_well: float
    read_noise: float
    bayer: bool
    nominal_exposure: float
    out_bits: int
    linear: bool
    mjpeg_quality: int
    tone_s: float
    sharpen: float
    denoise: float
    exposure: ControlRange
    gain: ControlRange
    white_balance: ControlRange | None
    auto: bool

    @property
    def sensitivity(self) -> float:
        """Relative signal per unit radiance per second (see the module doc)."""
        return SIM_EXPOSURE / self.nominal_exposure


#: A 1280x720 UVC webcam streaming MJPEG at 30 fps.
WEBCAM = CameraProfile(
    name="webcam",
    density=0.6,
    distortion=(-0.12, 0.04, 0.0, 0.0, 0.0),
    blur_px=0.6,
    vignetting=2.0,
    frame_interval=1.0 / 30.0,
    readout=0.028,
    queue=4,
    triggered=False,
    raw_bits=10,
    full_well=6000.0,
    read_noise=6.0,
    bayer=True,
    nominal_exposure=1.0 / 30.0,
    out_bits=8,
    linear=False,
    mjpeg_quality=80,
    tone_s=0.25,
    sharpen=0.6,
    denoise=0.6,
    exposure=ControlRange(0.0001, 0.5, 0.0001),  # V4L2 exposure_absolute: 1..5000 x 100 us
    gain=ControlRange(1.0, 8.0, 1.0 / 32.0),
    white_balance=ControlRange(2800.0, 6500.0, 10.0),
    auto=True,
)

#: A DSLR tethered for raw stills: slow, linear 14-bit, mechanical (global) shutter.
DSLR = CameraProfile(
    name="dslr",
    density=2.4,
    distortion=(-0.04, 0.01, 0.0, 0.0, 0.0),
    blur_px=0.5,
    vignetting=1.0,
    frame_interval=0.6,
    readout=0.0,
    queue=0,
    triggered=True,
    raw_bits=14,
    full_well=40000.0,
    read_noise=3.0,
    bayer=True,
    nominal_exposure=1.0 / 15.0,
    out_bits=14,
    linear=True,
    mjpeg_quality=0,
    tone_s=0.0,
    sharpen=0.0,
    denoise=0.0,
    exposure=ControlRange(1.0 / 8000.0, 30.0, 0.0),
    gain=ControlRange(1.0, 64.0, 0.0),  # ISO 100..6400
    white_balance=None,
    auto=False,
)

#: A machine-vision camera: mono 12-bit linear, global shutter, exposure in microseconds.
MONO12 = CameraProfile(
    name="mono12",
    density=1.2,
    distortion=(-0.08, 0.02, 0.0, 0.0, 0.0),
    blur_px=0.5,
    vignetting=1.0,
    frame_interval=0.004,
    readout=0.0,
    queue=0,
    triggered=True,
    raw_bits=12,
    full_well=10000.0,
    read_noise=4.0,
    bayer=False,
    nominal_exposure=1.0 / 30.0,
    out_bits=12,
    linear=True,
    mjpeg_quality=0,
    tone_s=0.0,
    sharpen=0.0,
    denoise=0.0,
    exposure=ControlRange(1e-5, 1.0, 1e-6),
    gain=ControlRange(1.0, 16.0, 0.0),
    white_balance=None,
    auto=False,
)

#: The profiles by name.
PROFILES: dict[str, CameraProfile] = {p.name: p for p in (WEBCAM, DSLR, MONO12)}
