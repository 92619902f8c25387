"""A physical simulator of projector, screen and camera (docs/MODEL.md section 5).

It stands in for hardware in tests, the demo and the evaluation. Everything is computed on
the projector's pixel grid (the capture set's ``space = "projector"``): value (H, W, 3) at
projector pixel x is what the camera sees of the screen point p(x).

The physics, per projector pixel x and camera channel i (linear units, 0..1 = camera full
scale before exposure):

    light_i(x; I) = g(x) * sum_j M[i, j] f_j(I_j)          projector light (primaries leak)
    radiance_i    = (a_i(x) + k_s max(R.V, 0)^n) * light_i + a_i(x) * ambient_i
    camera_i      = response(clip(exposure * vignette(x) * radiance_i + noise, 0, 1))

with f_j(I) = leak + (1 - leak) (I/255)^gamma_j the projector's response, g(x) the
cos(incidence)/r^2 fall-off, a(x) the diffuse albedo (coloured, possibly textured), k_s and n
the specular lobe (white: the colour of the light that hits it, scaled by what is projected at
that pixel), vignette the camera's cos^4 fall-off, noise Gaussian with read and shot parts,
averaged over several frames, then quantised to 8 bits.

The "eye" used by the evaluation is the same camera moved to the eye position, without noise
and without vignetting: an ideal observer that still quantises to 8 bits.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass, field, replace

import numpy as np

from viewcomp.calib.errors import ViewcompError
from viewcomp.calib.world.geometry import ScreenGeometry, irradiance_falloff
from viewcomp.calib.world.response import Response, parse_response
from viewcomp.calib.world.rig import Rig, default_rig

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


class SimulatorError(ViewcompError, ValueError):
    """A simulator parameter is out of range or unknown."""


@dataclass(frozen=True)
class ProjectorPhysics:
    """The projector: per-channel response and primaries as the camera sees them.

    ``primaries[i, j]``: camera channel i per unit light of projector channel j (cross-talk
    off the diagonal). ``gamma`` (3,) and ``leak`` (light at level 0, fraction of full).
    """

    gamma: tuple[float, float, float] = (2.2, 2.0, 2.4)
    leak: float = 0.004
    primaries: tuple[tuple[float, float, float], ...] = (
        (0.80, 0.10, 0.02),
        (0.08, 0.80, 0.10),
        (0.02, 0.08, 0.80),
    )

    def response(self, levels: np.ndarray) -> np.ndarray:
        """f(I): levels (..., 3) in 0..255 -> linear light (..., 3) in leak..1 per channel."""
        x = np.clip(np.asarray(levels, np.float64) / 255.0, 0.0, 1.0)
        return self.leak + (1.0 - self.leak) * x ** np.asarray(self.gamma)

    def response_inverse(self, light: np.ndarray) -> np.ndarray:
        """f^-1: linear light (..., 3) -> levels (..., 3) in 0..255 (float, not rounded)."""
        x = np.clip((np.asarray(light, np.float64) - self.leak) / (1.0 - self.leak), 0.0, 1.0)
        return 255.0 * x ** (1.0 / np.asarray(self.gamma))

    @property
    def mixing(self) -> np.ndarray:
        """(3, 3) primaries matrix."""
        return np.asarray(self.primaries, np.float64)


@dataclass(frozen=True)
class CameraPhysics:
    """The camera: exposure, vignetting, noise and quantisation (response comes from the rig)."""

    exposure: float = 0.80
    vignetting: bool = True
    read_noise: float = 0.002  # linear units, one frame
    shot_noise: float = 1e-4  # variance per unit signal, one frame
    frames: int = 4  # frames averaged per capture
    bits: int = 8


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

    def lobe(self, screen: Screen, eye: np.ndarray) -> np.ndarray:
        """k_s max(R.V, 0)^n for an eye at ``eye``: (H, W)."""
        if screen.k_s == 0:
            return np.zeros(self.shape)
        rv = np.maximum(self.geometry.rv(eye), 0.0)
        return screen.k_s * rv**screen.shininess

    def radiance(self, screen: Screen, image: np.ndarray, eye: np.ndarray) -> np.ndarray:
        """What leaves each screen point toward ``eye``: (H, W, 3) linear, before the camera."""
        a = screen.albedo_map(self.shape)
        refl = a + self.lobe(screen, eye)[..., None]
        return refl * self.light(image) + a * np.asarray(self.ambient)

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

    def capture(self, screen: Screen, image: np.ndarray, key: str) -> np.ndarray:
        """What the calibration camera records: encoded (H, W, 3), with noise and vignetting."""
        lin = self.expose(self.radiance(screen, image, self.geometry.camera), vignetting=True)
        return self.quantise(self.noise(lin, key))

    def observe(self, screen: Screen, image: np.ndarray, eye: np.ndarray) -> np.ndarray:
        """What an ideal eye at ``eye`` sees (no noise, no vignetting): (H, W, 3) uint8."""
        return self.quantise(self.expose(self.radiance(screen, image, eye), vignetting=False))

    def observe_linear(self, screen: Screen, image: np.ndarray, eye: np.ndarray) -> np.ndarray:
        """The eye's linear signal before clipping and quantisation: (H, W, 3)."""
        return self.expose(self.radiance(screen, image, eye), vignetting=False)

    # -- the true model, for the oracle ------------------------------------------------

    def true_mixing(self, screen: Screen, eye: np.ndarray, vignetting: bool) -> np.ndarray:
        """The exact per-pixel matrix M(x) with signal = M(x) f(I) + A(x): (H, W, 3, 3)."""
        a = screen.albedo_map(self.shape)
        refl = a + self.lobe(screen, eye)[..., None]
        scale = self.camera.exposure * self.falloff
        if vignetting and self.camera.vignetting:
            scale = scale * self.vignette
        return (refl * scale[..., None])[..., :, None] * self.projector.mixing

    def true_ambient(self, screen: Screen, vignetting: bool) -> np.ndarray:
        """The exact per-pixel ambient term A(x) of the camera signal: (H, W, 3)."""
        a = screen.albedo_map(self.shape)
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
    """The rig of the simulated world: docs/INTERFACES.md's example with a 16-degree projector."""
    rig = default_rig()
    return replace(rig, projector=replace(rig.projector, fov_y=SIM_PROJECTOR_FOV))
