"""The emulated rig: :func:`open_emulator` builds a projector, a camera and their clock over
the simulator's world, and keeps the truth for evaluation.

The geometry is the one `viewcomp capture --simulate` uses (the simulation rig, or a
template, with the projector at ``projector_size`` and the camera scaled with it:
:func:`~viewcomp.calib.sim.simcamera.scaled_camera_rig`); the camera's resolution then
follows the profile's pixel density (a webcam sees a 1920x1080 projector's frame at about
0.6 camera pixels per projector pixel) and its lens is the profile's. The two screens of a
capture are ``"white"`` (the ideal white board) and ``"screen"`` (the real one); the capture
procedure's prompt asks a person to swap them, :meth:`Emulator.swap_screen` does it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from os import PathLike

import numpy as np

from viewcomp.calib.emu.camera import EmulatedCamera
from viewcomp.calib.emu.clock import VirtualClock
from viewcomp.calib.emu.dlp import DlpModel
from viewcomp.calib.emu.faults import Faults
from viewcomp.calib.emu.profiles import PROFILES, SIM_EXPOSURE, CameraProfile
from viewcomp.calib.emu.projector import EmulatedProjector
from viewcomp.calib.emu.scene import SceneView
from viewcomp.calib.sim.simcamera import scaled_camera_rig
from viewcomp.calib.sim.simulator import (
    AnyScreen,
    MaterialScreen,
    ProjectorPhysics,
    Screen,
    Simulator,
    SimulatorError,
    make_screen,
    material_screen,
    simulation_rig,
    white_screen,
)
from viewcomp.calib.world.rig import Rig

#: The simulator's camera density (camera pixels per projector pixel) of scaled_camera_rig.
SIM_DENSITY = 1.2
#: The room light (the simulator's default).
AMBIENT = (0.015, 0.015, 0.018)


@dataclass
class EmulatorTruth:
    """What the emulator knows and the capture must learn: the true ``rig`` (the camera's
    resolution and lens included), the ``screens``, the projector's light ``model`` and
    ``mixing`` (3, 3) primaries, and the ``simulator`` of that world (its projector response
    is not the emulated one: use :meth:`observe_linear`)."""

    rig: Rig
    screens: dict[str, AnyScreen]
    model: DlpModel
    mixing: np.ndarray
    simulator: Simulator
    latency: int

    def observe_linear(self, screen: str, image: np.ndarray, eye: np.ndarray) -> np.ndarray:
        """What an ideal eye at ``eye`` (3,) metres sees of pattern ``image`` (H, W, 3) uint8
        on screen ``screen``, averaged over whole refresh periods: (H, W, 3) float64 linear
        on the projector grid, in the simulator's units (exposure 0.8, no vignetting; compare
        with :meth:`Simulator.observe_linear`)."""
        sim = self.simulator
        scr = self.screens[screen]
        light = sim.falloff[..., None] * (self.model.steady(image) @ self.mixing.T)
        rad = sim.reflectance(scr, eye) * light + sim.diffuse_albedo(scr) * np.asarray(AMBIENT)
        return SIM_EXPOSURE * rad


@dataclass
class Emulator:
    """The emulated devices: ``projector``, ``camera``, their ``clock``, and the ``truth``."""

    projector: EmulatedProjector
    camera: EmulatedCamera
    clock: VirtualClock
    truth: EmulatorTruth
    screen_name: str = "white"
    profile: CameraProfile = field(default=PROFILES["webcam"])

    def swap_screen(self, name: str) -> None:
        """Put screen ``name`` (``"white"`` or ``"screen"``) in front of the projector."""
        if name not in self.truth.screens:
            raise ValueError(f"no emulated screen {name!r}; have {', '.join(self.truth.screens)}")
        self.screen_name = name

    def close(self) -> None:
        """Close both devices."""
        self.projector.close()
        self.camera.close()


def _screen(
    screen: str | PathLike[str] | AnyScreen, gloss: str, shape: tuple[int, int], seed: int
) -> AnyScreen:
    if isinstance(screen, Screen | MaterialScreen):
        return screen
    text = str(screen)
    if text.endswith(".npz"):
        return material_screen(text)
    return make_screen(text, gloss, shape=shape, seed=seed)


def _profile(profile: str | CameraProfile) -> CameraProfile:
    """The camera profile named ``profile`` (one of :data:`PROFILES`), or ``profile`` itself.

    Raises:
        SimulatorError: an unknown name.
    """
    if isinstance(profile, str):
        if profile not in PROFILES:
            raise SimulatorError(
                f"unknown camera profile {profile!r}: use one of {', '.join(PROFILES)}"
            )
        return PROFILES[profile]
    return profile


def _true_rig(
    rig: Rig | None,
    size: tuple[int, int],
    camera_size: tuple[int, int] | None,
    prof: CameraProfile,
    supersample: int | None,
) -> tuple[Rig, int]:
    """The emulator's true geometry and its scene supersampling (see :func:`open_emulator`):
    ``rig`` (None: the simulation rig) with the projector at ``size`` (W, H) and the camera
    at ``camera_size`` (W, H; None: from the profile's density) with the profile's
    distortion; the supersampling ``supersample`` or enough for two samples per projector
    pixel (at least 2)."""
    base = rig or simulation_rig()
    base = replace(
        base,
        projector=replace(base.projector, resolution=size, principal_point=None),
    )
    scaled = scaled_camera_rig(base, size)
    sw, sh = scaled.camera.resolution
    if camera_size is None:
        k = prof.density / SIM_DENSITY
        camera_size = (max(16, round(sw * k)), max(16, round(sh * k)))
    cw, ch = camera_size
    density = SIM_DENSITY * cw / sw
    factor = supersample or max(2, math.ceil(2.0 / density))
    true_rig = replace(
        scaled,
        camera=replace(
            scaled.camera,
            resolution=(int(cw), int(ch)),
            principal_point=None,
            distortion=prof.distortion,
        ),
    )
    return true_rig, factor


def open_emulator(
    profile: str | CameraProfile = "webcam",
    screen: str | PathLike[str] | AnyScreen = "magenta",
    seed: int = 0,
    projector_size: tuple[int, int] = (160, 80),
    camera_size: tuple[int, int] | None = None,
    *,
    gloss: str = "glossy",
    faults: Faults | None = None,
    dlp: DlpModel | None = None,
    rig: Rig | None = None,
    supersample: int | None = None,
    latency: int | None = None,
) -> Emulator:
    """An emulated projector and camera over the simulator's world.

    Args:
        profile: ``"webcam"``, ``"dslr"``, ``"mono12"`` or a :class:`CameraProfile`.
        screen: the real screen: a colour name (with ``gloss``: :func:`make_screen`), the
            path of a measured material's ``.npz``, or a screen already made.
        seed: everything random (latency, noise, automatic modes, probabilistic faults).
        projector_size: (W, H) of the projector.
        camera_size: (W, H) of the camera; None: from the profile's density.
        faults: what to inject (:class:`Faults`).
        dlp: the projector's light (None: :class:`DlpModel`'s defaults).
        rig: the geometry (None: the simulation rig); its projector and camera resolutions
            are replaced.
        supersample: scene samples per camera pixel along each axis (None: enough for
            two per projector pixel, at least 2).
        latency: the projector's latency in refreshes (None: drawn from ``seed`` in 2..4).

    Raises:
        SimulatorError: an unknown profile or screen.
        MaterialError: a material file that cannot be used.
    """
    prof = _profile(profile)
    size = (int(projector_size[0]), int(projector_size[1]))
    true_rig, factor = _true_rig(rig, size, camera_size, prof, supersample)
    mixing = ProjectorPhysics().mixing
    model = dlp or DlpModel()
    sim = Simulator(rig=true_rig, ambient=AMBIENT, seed=seed)
    screens = {"white": white_screen(), "screen": _screen(screen, gloss, sim.shape, seed)}
    scene = SceneView(true_rig, factor, mixing, AMBIENT, prof.vignetting)
    flt = faults or Faults()
    bumped = None
    if flt.bump_at is not None:
        bumped = SceneView(
            _bumped(true_rig, flt.bump_at[1]), factor, mixing, AMBIENT, prof.vignetting
        )
    clock = VirtualClock()
    projector = EmulatedProjector(
        clock, size, model, np.random.default_rng([seed, 0xD1]), flt, latency
    )
    holder: list[Emulator] = []
    camera = EmulatedCamera(
        clock,
        projector,
        prof,
        (scene, bumped),
        screens,
        lambda: holder[0].screen_name,
        seed=seed,
        faults=flt,
    )
    truth = EmulatorTruth(true_rig, screens, model, mixing, sim, projector.latency)
    emu = Emulator(projector, camera, clock, truth, "white", prof)
    holder.append(emu)
    return emu


def _bumped(rig: Rig, px: float) -> Rig:
    """The rig with the camera moved sideways (position and look_at together) so the screen
    moves about ``px`` camera pixels left in its image (right for px < 0)."""
    cam = rig.camera
    rot, _ = cam.pose()
    pos = np.asarray(cam.position, np.float64)
    depth = float(np.linalg.norm(np.asarray(cam.look_at, np.float64) - pos))
    d = rot[0] * (px * depth / cam.focal())  # along the image's +x: the scene moves -x
    return replace(
        rig,
        camera=replace(
            cam,
            position=_point(pos + d),
            look_at=_point(np.asarray(cam.look_at) + d),
        ),
    )


def _point(v: np.ndarray) -> tuple[float, float, float]:
    """A point (3,) as the rig's (x, y, z) floats."""
    return (float(v[0]), float(v[1]), float(v[2]))
