"""A physical simulator of projector, screen and camera (docs/MODEL.md section 5).

It stands in for hardware in tests, the demo and the evaluation. Everything is computed on
the projector's pixel grid (the capture set's ``space = "projector"``): value (H, W, 3) at
projector pixel x is what the camera sees of the screen point p(x).

The physics, per projector pixel x and camera channel i (linear units, 0..1 = camera full
scale before exposure):

    light_i(x; I) = g(x) * sum_j M[i, j] f_j(I_j)          projector light (primaries leak)
    radiance_i    = rho_i(x, eye) * light_i + a_i(x) * ambient_i
    camera_i      = response(clip(exposure * vignette(x) * radiance_i + noise, 0, 1))

with f_j(I) the projector's response (:class:`ProjectorPhysics`: leak + (1 - leak)
(I/255)^gamma_j, or the kinked response of a DLP-like projector), g(x) the cos(incidence)/r^2
fall-off, rho(x, eye) the screen's reflectance (:meth:`Simulator.reflectance`, relative to a
white Lambertian surface of albedo 1), a(x) the albedo the room's diffuse light sees, vignette
the camera's cos^4 fall-off, noise Gaussian with read and shot parts, averaged over several
frames, then quantised to 8 bits.

Two kinds of screen:
- :class:`Screen`, analytic: rho = a(x) + k_s max(R.V, 0)^n, a diffuse albedo (coloured,
  possibly textured) plus a white Phong lobe (the colour of the light that hits it, scaled by
  what is projected at that pixel);
- :class:`MaterialScreen`, measured: rho = pi * BRDF of a measured material
  (:mod:`viewcomp.calib.sim.materials`) averaged over the projector's lens, a disk of finite
  size; a(x) is its reflectance with light along the normal seen 45 degrees off.

The "eye" used by the evaluation is the same camera moved to the eye position, without noise
and without vignetting: an ideal observer that still quantises to 8 bits.
"""

from __future__ import annotations

import math
import zlib
from collections import OrderedDict
from dataclasses import dataclass, field, replace
from os import PathLike

import numpy as np

from viewcomp.calib.errors import SimulatorError
from viewcomp.calib.io.hdr import check_stops, merge_exposures
from viewcomp.calib.sim.materials import (
    Material,
    lens_averaged_reflectance,
    lens_samples,
    load_material,
)
from viewcomp.calib.world.geometry import ScreenGeometry, irradiance_falloff
from viewcomp.calib.world.response import Response, parse_response
from viewcomp.calib.world.rig import Rig, default_rig
from viewcomp.calib.world.tracker import with_default_tracker

# Diffuse albedo per camera channel of the named screens.
SCREEN_COLOURS: dict[str, tuple[float, float, float]] = {
    "white": (0.85, 0.85, 0.85),
    "red": (0.70, 0.16, 0.14),
    "green": (0.16, 0.60, 0.20),
    "blue": (0.14, 0.20, 0.62),
    "magenta": (0.66, 0.16, 0.58),
    "yellow": (0.70, 0.64, 0.16),
    "cyan": (0.16, 0.58, 0.62),
    "textured": (0.60, 0.45, 0.35),  # mean colour; the texture is added per pixel
}

# Specular lobe (k_s, shininess n) of the gloss presets.
GLOSS_PRESETS: dict[str, tuple[float, float]] = {
    "matte": (0.0, 1.0),
    "satin": (0.12, 8.0),
    "glossy": (0.30, 30.0),
}

WHITE_ALBEDO = 0.85


@dataclass(frozen=True)
class ProjectorPhysics:
    """The projector: per-channel response and primaries as the camera sees them.

    ``primaries[i, j]``: camera channel i per unit light of projector channel j (cross-talk
    off the diagonal). ``gamma`` (3,), ``leak`` (light at level 0, fraction of full: one
    number or one per channel; broadcasts against (..., 3)).

    Without ``kink`` the response is the power law f(I) = leak + (1 - leak) x^gamma with
    x = I/255. With ``kink`` (3,) = x_k in (0, 1) per channel, the body x^gamma continues
    above x_k as a straight line whose slope is ``kink_slope`` (3,) times the body's slope
    at x_k (a DLP's white segment: the top of the range rises more slowly):

        h(x) = x^gamma                                            x <= x_k
        h(x) = x_k^gamma + s gamma x_k^(gamma - 1) (x - x_k)      x >  x_k
        f(I) = leak + (1 - leak) h(x) / h(1)

    so f(0) = leak, f(255) = 1, f increasing (s > 0), and :meth:`response_inverse` inverts it
    exactly (to rounding).
    """

    gamma: tuple[float, float, float] = (2.2, 2.0, 2.4)
    leak: float | tuple[float, float, float] = 0.004
    primaries: tuple[tuple[float, float, float], ...] = (
        (0.80, 0.10, 0.02),
        (0.08, 0.80, 0.10),
        (0.02, 0.08, 0.80),
    )
    kink: tuple[float, float, float] | None = None
    kink_slope: tuple[float, float, float] = (1.0, 1.0, 1.0)

    def __post_init__(self) -> None:
        leak = np.asarray(self.leak, np.float64)
        if leak.shape not in ((), (3,)) or np.any(leak < 0) or np.any(leak >= 1):
            raise SimulatorError(f"projector leak is one number or three in 0..1, got {self.leak}")
        if self.kink is not None:
            k = np.asarray(self.kink, np.float64)
            s = np.asarray(self.kink_slope, np.float64)
            if k.shape != (3,) or np.any(k <= 0) or np.any(k >= 1):
                raise SimulatorError(f"projector kink is three levels in (0, 1), got {self.kink}")
            if s.shape != (3,) or np.any(s <= 0):
                raise SimulatorError(
                    f"projector kink_slope is three factors > 0, got {self.kink_slope}"
                )

    @classmethod
    def dlp(cls) -> ProjectorPhysics:
        """A measured-DLP-like projector (:data:`DLP_PROJECTOR`): a black leak of 2.5-3.5% of
        white and a kink near white, both per channel."""
        return DLP_PROJECTOR

    def _body(self, x: np.ndarray) -> np.ndarray:
        """h(x) / h(1) for x (..., 3) in 0..1 (kinked response only)."""
        g = np.asarray(self.gamma, np.float64)
        k = np.asarray(self.kink, np.float64)
        s = np.asarray(self.kink_slope, np.float64)
        hk = k**g
        slope = s * g * k ** (g - 1.0)
        top = hk + slope * (1.0 - k)
        return np.where(x <= k, x**g, hk + slope * (x - k)) / top

    def response(self, levels: np.ndarray) -> np.ndarray:
        """f(I): levels (..., 3) in 0..255 -> linear light (..., 3) in leak..1 per channel."""
        x = np.clip(np.asarray(levels, np.float64) / 255.0, 0.0, 1.0)
        leak = np.asarray(self.leak, np.float64)
        if self.kink is None:
            return leak + (1.0 - leak) * x ** np.asarray(self.gamma)
        return leak + (1.0 - leak) * self._body(x)

    def response_inverse(self, light: np.ndarray) -> np.ndarray:
        """f^-1: linear light (..., 3) -> levels (..., 3) in 0..255 (float, not rounded)."""
        leak = np.asarray(self.leak, np.float64)
        y = np.clip((np.asarray(light, np.float64) - leak) / (1.0 - leak), 0.0, 1.0)
        g = np.asarray(self.gamma, np.float64)
        if self.kink is None:
            return 255.0 * y ** (1.0 / g)
        k = np.asarray(self.kink, np.float64)
        s = np.asarray(self.kink_slope, np.float64)
        hk = k**g
        slope = s * g * k ** (g - 1.0)
        h = y * (hk + slope * (1.0 - k))
        x = np.where(h <= hk, h ** (1.0 / g), k + (h - hk) / slope)
        return 255.0 * np.clip(x, 0.0, 1.0)

    @property
    def mixing(self) -> np.ndarray:
        """(3, 3) primaries matrix."""
        return np.asarray(self.primaries, np.float64)


#: A measured-DLP-like projector: per channel a black leak of 2.5, 3 and 3.5% of white, a
#: power-law body and, at 88, 86 and 90% of the input, a kink where the slope falls to 0.5,
#: 0.45 and 0.55 of the body's (the white segment of a colour wheel).
DLP_PROJECTOR = ProjectorPhysics(
    gamma=(2.3, 2.1, 2.5),
    leak=(0.025, 0.030, 0.035),
    kink=(0.88, 0.86, 0.90),
    kink_slope=(0.50, 0.45, 0.55),
)

#: The projector presets by name (``viewcomp simulate --projector``).
PROJECTOR_PRESETS: dict[str, ProjectorPhysics] = {
    "default": ProjectorPhysics(),
    "dlp": DLP_PROJECTOR,
}


@dataclass(frozen=True)
class CameraPhysics:
    """The camera: exposure, vignetting, noise and quantisation (response comes from the rig).

    ``hdr_stops``: None for one exposure per capture (encoded codes of ``bits`` bits), or the
    relative exposures of an HDR bracket (e.g. :data:`~viewcomp.calib.io.hdr.DEFAULT_STOPS`):
    each capture is then taken at ``exposure * stop`` for every stop, each frame with its own
    noise and quantised to ``bits`` bits, and merged by
    :func:`~viewcomp.calib.io.hdr.merge_exposures` into float32 linear light in units of
    ``exposure`` (values above 1 are light a single exposure would clip).
    """

    exposure: float = 0.80
    vignetting: bool = True
    read_noise: float = 0.002  # linear units, one frame
    shot_noise: float = 1e-4  # variance per unit signal, one frame
    frames: int = 4  # frames averaged per capture
    bits: int = 8
    hdr_stops: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.exposure) and self.exposure > 0):
            raise SimulatorError(f"camera exposure must be finite and > 0, got {self.exposure}")
        if self.hdr_stops is not None:
            try:
                check_stops(self.hdr_stops)
            except ValueError as exc:
                raise SimulatorError(f"camera hdr_stops: {exc}") from None


@dataclass(frozen=True)
class Screen:
    """A screen: diffuse albedo (3,) or a per-pixel map (H, W, 3), and a white specular lobe."""

    name: str
    albedo: np.ndarray
    k_s: float = 0.0
    shininess: float = 1.0

    def albedo_map(self, shape: tuple[int, int]) -> np.ndarray:
        """(H, W, 3) albedo on the projector grid."""
        a = np.asarray(self.albedo, np.float64)
        if a.ndim == 1:
            return np.broadcast_to(a, (*shape, 3))
        if a.shape[:2] != shape:
            raise SimulatorError(f"albedo map is {a.shape[:2]}, projector grid is {shape}")
        return a


#: Default projector lens of a material screen: radius in metres and points on the disk.
LENS_RADIUS_M = 0.0075
LENS_SAMPLES = 16

#: Reflectances a material screen keeps (one per eye and projector), most recent last.
REFLECTANCE_CACHE = 16

#: Digits (of a metre) an eye is rounded to as the key of the reflectance cache: 0.1 mm.
_EYE_DIGITS = 4

#: The directions the diffuse albedo of a material is read at: light along the normal, seen
#: 45 degrees off it, far from the mirror direction (the normal), so no highlight is in it.
_DIFFUSE_WI = (0.0, 0.0, 1.0)
_DIFFUSE_WO = (math.sqrt(0.5), 0.0, math.sqrt(0.5))


@dataclass(eq=False)
class MaterialScreen:
    """A screen of a measured material (:mod:`viewcomp.calib.sim.materials`), lit through a
    projector lens of finite size.

    Its reflectance toward an eye is the material's, averaged over ``lens_samples`` points of
    the projector's lens, a disk of ``lens_radius_m`` metres (:func:`lens_averaged_reflectance`);
    the simulator computes it (:meth:`Simulator.reflectance`) and keeps the last
    :data:`REFLECTANCE_CACHE` results here, keyed by the projector and the eye rounded to
    0.1 mm. ``diffuse`` (3,) is the material's reflectance with light along the normal seen
    45 degrees off it: the albedo the room's (diffuse) light sees. Equality is identity.
    """

    name: str
    material: Material
    lens_radius_m: float = LENS_RADIUS_M
    lens_samples: int = LENS_SAMPLES
    diffuse: np.ndarray = field(init=False, repr=False)
    _cache: OrderedDict[tuple[object, ...], np.ndarray] = field(
        init=False, repr=False, default_factory=OrderedDict
    )

    def __post_init__(self) -> None:
        if not (math.isfinite(self.lens_radius_m) and self.lens_radius_m >= 0):
            raise SimulatorError(
                f"lens_radius_m is the projector lens's radius in metres, >= 0, got "
                f"{self.lens_radius_m}"
            )
        if self.lens_samples < 1:
            raise SimulatorError(f"lens_samples must be >= 1, got {self.lens_samples}")
        d = self.material.reflectance(np.asarray(_DIFFUSE_WI), np.asarray(_DIFFUSE_WO))
        d.setflags(write=False)
        self.diffuse = d


def material_screen(
    material: str | PathLike[str] | Material,
    lens_radius_m: float = LENS_RADIUS_M,
    lens_samples: int = LENS_SAMPLES,
) -> MaterialScreen:
    """A screen of a measured material: a :class:`Material` or the path of its ``.npz``.

    Raises:
        MaterialError: the file cannot be used (the message names it and the fix).
        SimulatorError: a negative lens radius or fewer than one lens sample.
    """
    mat = material if isinstance(material, Material) else load_material(material)
    return MaterialScreen(
        name=mat.name, material=mat, lens_radius_m=lens_radius_m, lens_samples=lens_samples
    )


#: Any screen the simulator shows: analytic (albedo + Phong lobe) or measured.
AnyScreen = Screen | MaterialScreen


def textured_albedo(shape: tuple[int, int], seed: int) -> np.ndarray:
    """A printed-poster-like albedo: soft colour blobs and a few stripes, values 0.1..0.8."""
    h, w = shape
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    base = np.asarray(SCREEN_COLOURS["textured"])
    a = np.broadcast_to(base, (h, w, 3)).copy()
    for _ in range(7):
        cy, cx = rng.uniform(0, h), rng.uniform(0, w)
        r = rng.uniform(0.08, 0.25) * w
        colour = rng.uniform(-0.25, 0.25, 3)
        a += colour * np.exp(-((xx - cx) ** 2 + (yy - cy) ** 2) / (2 * r * r))[..., None]
    stripes = (np.sin(2 * np.pi * xx / (w / 9.0)) > 0.85).astype(np.float64)
    a += stripes[..., None] * np.array([-0.15, 0.05, 0.10])
    return np.clip(a, 0.1, 0.8)


def make_screen(
    colour: str | tuple[float, float, float],
    gloss: str | tuple[float, float] = "glossy",
    shape: tuple[int, int] | None = None,
    seed: int = 0,
) -> Screen:
    """A screen from a colour name or an (R, G, B) albedo in 0..1 and a gloss preset or (k_s, n).

    Raises:
        SimulatorError: an unknown name, an albedo outside 0..1, a negative lobe.
    """
    if isinstance(colour, str):
        if colour not in SCREEN_COLOURS:
            raise SimulatorError(
                f"unknown screen {colour!r}: use one of {', '.join(SCREEN_COLOURS)} or R,G,B "
                "albedos in 0..1"
            )
        name = colour
        albedo = np.asarray(SCREEN_COLOURS[colour], np.float64)
        if colour == "textured":
            if shape is None:
                raise SimulatorError("a textured screen needs the projector grid's shape")
            albedo = textured_albedo(shape, seed)
    else:
        albedo = np.asarray(colour, np.float64)
        if albedo.shape != (3,) or np.any(albedo < 0) or np.any(albedo > 1):
            raise SimulatorError(f"a screen albedo is three numbers in 0..1, got {colour!r}")
        name = ",".join(f"{v:g}" for v in albedo)
    if isinstance(gloss, str):
        if gloss not in GLOSS_PRESETS:
            raise SimulatorError(f"unknown gloss {gloss!r}: use one of {', '.join(GLOSS_PRESETS)}")
        k_s, n = GLOSS_PRESETS[gloss]
    else:
        k_s, n = gloss
    if k_s < 0 or n <= 0:
        raise SimulatorError(f"a specular lobe needs k_s >= 0 and shininess > 0, got {gloss!r}")
    return Screen(name=name, albedo=albedo, k_s=float(k_s), shininess=float(n))


def white_screen() -> Screen:
    """The ideal matte white reference screen."""
    return Screen(name="white-reference", albedo=np.full(3, WHITE_ALBEDO), k_s=0.0)


@dataclass
class Simulator:
    """Projector + screen + camera on one rig. Deterministic for a given ``seed``."""

    rig: Rig = field(default_factory=default_rig)
    projector: ProjectorPhysics = field(default_factory=ProjectorPhysics)
    camera: CameraPhysics = field(default_factory=CameraPhysics)
    ambient: tuple[float, float, float] = (0.015, 0.015, 0.018)
    seed: int = 0

    def __post_init__(self) -> None:
        self.geometry = ScreenGeometry.from_rig(self.rig)
        self.falloff = irradiance_falloff(self.geometry.pos, self.geometry.projector)
        self.response: Response = parse_response(self.rig.camera.response)
        self.vignette = self._vignette()

    @property
    def shape(self) -> tuple[int, int]:
        """(H, W) of the projector grid."""
        return self.geometry.pos.shape[:2]

    def _vignette(self) -> np.ndarray:
        cam = self.geometry.camera
        axis = np.asarray(self.rig.camera.look_at, float) - cam
        axis /= np.linalg.norm(axis)
        d = self.geometry.pos - cam
        cos_phi = (d @ axis) / np.linalg.norm(d, axis=-1)
        return cos_phi**4

    def with_rig(self, rig: Rig) -> Simulator:
        """The same physics on another rig."""
        return replace(self, rig=rig)

    # -- the physics -------------------------------------------------------------------

    def light(self, image: np.ndarray) -> np.ndarray:
        """Projector light reaching each screen point, per camera channel: (H, W, 3) linear."""
        img = np.asarray(image, np.float64)
        if img.shape != (*self.shape, 3):
            raise SimulatorError(f"image must be {(*self.shape, 3)}, got {img.shape}")
        return self.falloff[..., None] * (self.projector.response(img) @ self.projector.mixing.T)

    def lobe(self, screen: AnyScreen, eye: np.ndarray) -> np.ndarray:
        """k_s max(R.V, 0)^n for an eye at ``eye``: (H, W). Analytic screens only (a
        measured material has no separate lobe: see :meth:`reflectance`)."""
        if not isinstance(screen, Screen):
            raise SimulatorError(
                f"screen {screen.name!r} is a measured material: it has no analytic lobe; use "
                "Simulator.reflectance"
            )
        if screen.k_s == 0:
            return np.zeros(self.shape)
        rv = np.maximum(self.geometry.rv(eye), 0.0)
        return screen.k_s * rv**screen.shininess

    def reflectance(self, screen: AnyScreen, eye: np.ndarray) -> np.ndarray:
        """The screen's reflectance of the projector's light toward ``eye`` (3,) metres.

        Relative to a white Lambertian surface of albedo 1 (``pi * BRDF``), per projector
        pixel's screen point: (H, W, 3) float64, >= 0, dimensionless. An analytic
        :class:`Screen` gives ``albedo + k_s max(R.V, 0)^n``; a :class:`MaterialScreen` its
        material averaged over the projector's lens (centre: the projector's position; axis:
        toward its look_at), kept per eye in the screen's cache (read-only arrays).
        """
        if isinstance(screen, Screen):
            return screen.albedo_map(self.shape) + self.lobe(screen, eye)[..., None]
        e = np.asarray(eye, np.float64)
        if e.shape != (3,):
            raise SimulatorError(f"eye must be (3,) metres, got shape {e.shape}")
        key = (self.rig.projector, *(round(float(v), _EYE_DIGITS) for v in e))
        cached = screen._cache.get(key)
        if cached is not None:
            screen._cache.move_to_end(key)
            return cached
        centre = self.geometry.projector
        axis = np.asarray(self.rig.projector.look_at, np.float64) - centre
        lens = lens_samples(centre, axis, screen.lens_radius_m, screen.lens_samples)
        refl = lens_averaged_reflectance(screen.material, self.geometry.pos, lens, e)
        refl.setflags(write=False)
        screen._cache[key] = refl
        while len(screen._cache) > REFLECTANCE_CACHE:
            screen._cache.popitem(last=False)
        return refl

    def diffuse_albedo(self, screen: AnyScreen) -> np.ndarray:
        """The albedo the room's (diffuse) light sees: (H, W, 3), 0..1 (a material's
        :attr:`MaterialScreen.diffuse` everywhere)."""
        if isinstance(screen, Screen):
            return screen.albedo_map(self.shape)
        return np.broadcast_to(screen.diffuse, (*self.shape, 3))

    def radiance(self, screen: AnyScreen, image: np.ndarray, eye: np.ndarray) -> np.ndarray:
        """What leaves each screen point toward ``eye``: (H, W, 3) linear, before the camera."""
        refl = self.reflectance(screen, eye)
        return refl * self.light(image) + self.diffuse_albedo(screen) * np.asarray(self.ambient)

    def expose(self, radiance: np.ndarray, vignetting: bool) -> np.ndarray:
        """Camera linear signal (before noise and clipping): (H, W, 3)."""
        lin = self.camera.exposure * radiance
        if vignetting and self.camera.vignetting:
            lin = lin * self.vignette[..., None]
        return lin

    def quantise(self, linear: np.ndarray) -> np.ndarray:
        """Clip, apply the camera response and quantise: (H, W, 3) uint8 or uint16."""
        enc = self.response.encode(np.clip(linear, 0.0, 1.0).astype(np.float32))
        top = (1 << self.camera.bits) - 1
        dtype = np.uint8 if self.camera.bits <= 8 else np.uint16
        return np.rint(enc * top).astype(dtype)

    def noise(self, linear: np.ndarray, key: str) -> np.ndarray:
        """Read + shot noise averaged over ``frames``, seeded by (seed, key)."""
        rng = np.random.default_rng([self.seed, zlib.crc32(key.encode())])
        var = self.camera.read_noise**2 + self.camera.shot_noise * np.maximum(linear, 0.0)
        sd = np.sqrt(var / max(self.camera.frames, 1))
        return linear + rng.standard_normal(linear.shape) * sd

    def record(self, linear: np.ndarray, key: str) -> np.ndarray:
        """What the camera writes of its linear signal ``linear`` (H, W, 3) (after exposure):
        encoded codes (:meth:`quantise` of :meth:`noise`), or, with ``camera.hdr_stops``, the
        bracket's frames (each ``linear * stop`` with its own noise, keyed ``key@stop``)
        merged into float32 linear light (:func:`~viewcomp.calib.io.hdr.merge_exposures`)."""
        stops = self.camera.hdr_stops
        if stops is None:
            return self.quantise(self.noise(linear, key))
        frames = [self.quantise(self.noise(linear * s, f"{key}@{s:g}")) for s in stops]
        return merge_exposures(frames, stops, self.response)[0]

    def capture(self, screen: AnyScreen, image: np.ndarray, key: str) -> np.ndarray:
        """What the calibration camera records: encoded (H, W, 3), with noise and vignetting
        (float32 linear with ``camera.hdr_stops``: see :meth:`record`)."""
        lin = self.expose(self.radiance(screen, image, self.geometry.camera), vignetting=True)
        return self.record(lin, key)

    def observe(self, screen: AnyScreen, image: np.ndarray, eye: np.ndarray) -> np.ndarray:
        """What an ideal eye at ``eye`` sees (no noise, no vignetting): (H, W, 3) uint8."""
        return self.quantise(self.expose(self.radiance(screen, image, eye), vignetting=False))

    def observe_linear(self, screen: AnyScreen, image: np.ndarray, eye: np.ndarray) -> np.ndarray:
        """The eye's linear signal before clipping and quantisation: (H, W, 3)."""
        return self.expose(self.radiance(screen, image, eye), vignetting=False)

    # -- the true model, for the oracle ------------------------------------------------

    def true_mixing(self, screen: AnyScreen, eye: np.ndarray, vignetting: bool) -> np.ndarray:
        """The exact per-pixel matrix M(x) with signal = M(x) f(I) + A(x): (H, W, 3, 3)."""
        refl = self.reflectance(screen, eye)
        scale = self.camera.exposure * self.falloff
        if vignetting and self.camera.vignetting:
            scale = scale * self.vignette
        return (refl * scale[..., None])[..., :, None] * self.projector.mixing

    def true_ambient(self, screen: AnyScreen, vignetting: bool) -> np.ndarray:
        """The exact per-pixel ambient term A(x) of the camera signal: (H, W, 3)."""
        a = self.diffuse_albedo(screen)
        amb = self.camera.exposure * a * np.asarray(self.ambient)
        if vignetting and self.camera.vignetting:
            amb = amb * self.vignette[..., None]
        return amb


# The simulated world uses the example rig of docs/INTERFACES.md with one change: the
# projector's vertical field of view is 16 degrees instead of 20 (a slightly longer zoom). With
# it, the mirror point of the projector seen from a viewer at 60 degrees (x = 0.134 m) lies at
# the very edge of the image (half-width 0.14 m), so, as in the paper's experiment, the
# highlight that dominates the view at 90 degrees "almost vanishes" at 60. At 20 degrees it
# stays well inside the image and the two views differ much less.
SIM_PROJECTOR_FOV = 16.0


def simulation_rig() -> Rig:
    """The rig of the simulated world: docs/INTERFACES.md's example with a 16-degree projector
    and, as ``[tracker]``, a webcam on the picture's top edge looking at the audience
    (:func:`viewcomp.calib.world.tracker.default_tracker`), so ``viewcomp track`` runs on it."""
    rig = default_rig()
    return with_default_tracker(
        replace(rig, projector=replace(rig.projector, fov_y=SIM_PROJECTOR_FOV))
    )
