"""The simulated calibration camera in its own image: what `simulate --space camera` writes.

:mod:`~viewcomp.calib.sim.simulator` computes everything on the projector's pixel grid. A real
camera sees the screen through its own pose and lens: the projector's frame is a distorted
quadrilateral in the camera image, surrounded by screen that only the room lights. This
module renders that image from the *same* physics:

for every camera pixel (u_c, v_c), row ``[v_c, u_c]`` of a (Hc, Wc) image:

1. its ray (``rig.camera.pixel_rays()``, lens distortion included) meets the screen z = 0 at p;
2. the projector pixel that lights p is x = ``rig.projector.project(p)`` (float, (u, v));
3. the screen's radiance toward the camera is :meth:`Simulator.radiance` on the projector grid,
   split into the part the projector lights and the ambient part, each sampled bilinearly at
   x; outside the projector's frame (u < -0.5 or u > W - 0.5, likewise v) only the ambient
   part remains (the unlit surround);
4. the camera: :meth:`Simulator.expose` (exposure), cos^4 vignetting of the angle between the
   pixel's ray and the camera's optical axis, a Gaussian blur (optics, ``blur_px`` camera
   pixels), :meth:`Simulator.noise`, then :meth:`Simulator.quantise` (response, 8 bits).

By default each camera pixel samples the screen at its centre (steps 1-3 at one point). With
``SimCamera(..., supersample=k)`` steps 1-4's optics run on k x k sub-pixels that are then
box-averaged: the pixel integrates over its area, as a real sensor does (what matters for a
camera coarser than the projector's finest Gray-code stripes).

Nothing of the physics is re-implemented here: albedo, lobe (R.V toward the camera), fall-off,
projector response, primaries and ambient come from the Simulator on the projector grid.

The simulated camera has a lens: a rig whose camera has no ``distortion`` gets
:data:`SIM_CAMERA_DISTORTION` (k1 = -0.08, k2 = 0.02) so that geometric calibration is
exercised. The rig.toml written with a camera-space capture set leaves the distortion out:
`viewcomp calibrate` estimates the lens, as it must for a real camera.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property
from pathlib import Path

import cv2
import numpy as np

from viewcomp.calib.io.captureset import write_capture_set
from viewcomp.calib.io.patterns import (
    chessboard,
    graycode_patterns,
    phase_patterns,
    table1_patterns,
)
from viewcomp.calib.sim.simulator import (
    AnyScreen,
    CameraPhysics,
    MaterialScreen,
    ProjectorPhysics,
    Screen,
    Simulator,
    make_screen,
    simulation_rig,
    white_screen,
)
from viewcomp.calib.world.geometry import meet_screen, screen_points_at
from viewcomp.calib.world.rig import CaptureSpec, Rig

# Frames the simulated camera averages per capture in camera space. The projector-space
# simulator's noise (CameraPhysics.frames = 4) is the noise of a capture as it lands on the
# projector grid; rectifying camera frames onto that grid interpolates ~1.4 camera pixels per
# projector pixel, which halves the noise variance, so 2 camera frames give the same noise per
# projector pixel (measured: tests/calib/geo/test_geocal.py, evaluation parity).
CAMERA_FRAMES = 2


def camera_simulator(
    rig: Rig,
    seed: int = 0,
    projector: ProjectorPhysics | None = None,
    exposure: float | None = None,
    hdr_stops: tuple[float, ...] | None = None,
) -> Simulator:
    """A simulator for camera-space captures on ``rig`` (``CAMERA_FRAMES`` per capture), with
    ``projector`` (None: the default :class:`ProjectorPhysics`), the camera's ``exposure``
    (None: :class:`CameraPhysics`'s) and HDR bracket ``hdr_stops`` (None: single exposures)."""
    camera = CameraPhysics(frames=CAMERA_FRAMES, hdr_stops=hdr_stops)
    if exposure is not None:
        camera = replace(camera, exposure=exposure)
    return Simulator(rig=rig, seed=seed, camera=camera, projector=projector or ProjectorPhysics())


SIM_CAMERA_DISTORTION: tuple[float, float, float, float, float] = (-0.08, 0.02, 0.0, 0.0, 0.0)
DEFAULT_BLUR_PX = 0.7
TABLE1_NAMES = ("black", "gray", "red", "green", "blue", "ramp")


def camera_rig(rig: Rig) -> Rig:
    """The rig as the simulated camera has it: ``space = "camera"`` and, if the camera has no
    ``distortion``, the default lens :data:`SIM_CAMERA_DISTORTION`."""
    cam = rig.camera
    if cam.distortion is None:
        cam = replace(cam, distortion=SIM_CAMERA_DISTORTION)
    return replace(rig, camera=cam, capture=CaptureSpec(space="camera"))


def scaled_camera_rig(rig: Rig, projector_size: tuple[int, int] | None) -> Rig:
    """:func:`camera_rig`, with the camera's resolution scaled by the factor that takes the
    simulation rig's projector width (640) to ``projector_size`` (None: unscaled), so a
    reduced world keeps about 1.2 camera pixels per projector pixel."""
    out = camera_rig(rig)
    if projector_size is None:
        return out
    f = projector_size[0] / simulation_rig().projector.resolution[0]
    cw, ch = out.camera.resolution
    size = (max(16, round(cw * f)), max(16, round(ch * f)))
    return replace(out, camera=replace(out.camera, resolution=size, principal_point=None))


def written_rig(rig: Rig) -> Rig:
    """The rig.toml of a simulated camera-space set: ``space = "camera"``, no distortion (the
    lens is for `calibrate` to estimate, as with a real camera)."""
    return replace(
        rig, camera=replace(rig.camera, distortion=None), capture=CaptureSpec(space="camera")
    )


@dataclass(frozen=True)
class CameraView:
    """Per-camera-pixel geometry of a rig (all (Hc, Wc) on the camera grid).

    ``map_u``, ``map_v``: float32 projector pixel coordinates (u right, v down) of the screen
    point each camera pixel sees (for ``cv2.remap`` of projector-grid arrays); ``inside``:
    bool, the point lies in the projector's frame; ``vignette``: cos^4 of the angle between
    the pixel's ray and the camera's optical axis, 0..1.
    """

    map_u: np.ndarray
    map_v: np.ndarray
    inside: np.ndarray
    vignette: np.ndarray


def camera_view(rig: Rig, supersample: int = 1) -> CameraView:
    """Cast every camera pixel's ray (with the camera's lens distortion) onto the screen.

    ``supersample`` k >= 1 casts k x k rays per camera pixel instead, through the centres of
    its k x k sub-cells: the view is then (k Hc, k Wc), sub-cell (i, j) of pixel (u, v) at
    ``[k v + j, k u + i]`` (what :class:`SimCamera` box-averages to integrate over the pixel).

    Raises:
        GeometryError: a camera pixel's ray does not reach the screen plane in front of it.
    """
    cam = rig.camera
    if not (isinstance(supersample, int) and supersample >= 1):
        raise ValueError(f"supersample must be an integer >= 1, got {supersample!r}")
    rays = cam.pixel_rays(cam.height * supersample, cam.width * supersample)  # unit, world
    origin = np.asarray(cam.position, np.float64)
    uv = rig.projector.project(meet_screen(origin, rays, "camera"))
    w, h = rig.projector.resolution
    u, v = uv[..., 0], uv[..., 1]
    inside = np.isfinite(u) & np.isfinite(v)
    inside &= (u >= -0.5) & (u <= w - 0.5) & (v >= -0.5) & (v <= h - 0.5)
    u = np.where(np.isfinite(u), u, -1e4)
    v = np.where(np.isfinite(v), v, -1e4)
    axis = np.asarray(cam.look_at, np.float64) - origin
    axis /= np.linalg.norm(axis)
    vignette = np.clip(rays @ axis, 0.0, 1.0) ** 4
    return CameraView(
        map_u=u.astype(np.float32),
        map_v=v.astype(np.float32),
        inside=inside,
        vignette=vignette.astype(np.float32),
    )


def true_camera_points(rig: Rig, points_uv: np.ndarray) -> np.ndarray:
    """Where the camera sees projector points: (..., 2) projector (u, v) -> (..., 2) camera
    pixels (lens included); the geometric truth that rectification must recover."""
    uv = np.asarray(points_uv, np.float64)
    if uv.shape[-1:] != (2,):
        raise ValueError(f"points_uv must have shape (..., 2), got {uv.shape}")
    return rig.camera.project(screen_points_at(rig.projector, uv))


def true_projector_map(rig: Rig) -> np.ndarray:
    """(H, W, 2) float64: camera pixel (x, y) of every projector pixel centre (the truth)."""
    w, h = rig.projector.resolution
    uu, vv = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    return true_camera_points(rig, np.stack([uu, vv], axis=-1))


class SimCamera:
    """The simulated camera of ``sim`` (whose rig gives both devices), rendering its own image.

    ``blur_px`` is the optics' Gaussian sigma in camera pixels. The rig must already carry the
    lens the simulation should use (see :func:`camera_rig`).

    ``supersample`` k: 1 (the default) samples the screen at each camera pixel's centre (a
    point-sampling camera); k > 1 renders k x k sub-pixels per camera pixel (the blur scaled
    alike) and box-averages them, so each pixel integrates the light over its area as a real
    sensor does. The difference matters when the camera is coarser than the projector's
    finest stripes (a camera pixel then sees several projector pixels and averages them).
    """

    def __init__(
        self, sim: Simulator, blur_px: float = DEFAULT_BLUR_PX, supersample: int = 1
    ) -> None:
        if blur_px < 0:
            raise ValueError(f"blur_px must be >= 0 camera pixels, got {blur_px}")
        if not (isinstance(supersample, int) and supersample >= 1):
            raise ValueError(f"supersample must be an integer >= 1, got {supersample!r}")
        self.sim = sim
        self.blur_px = float(blur_px)
        self.supersample = supersample
        # the same physics without the room light: radiance - lit = the ambient part
        self._lit_sim = replace(sim, ambient=(0.0, 0.0, 0.0))
        self._ambient: tuple[AnyScreen, np.ndarray] | None = None  # last screen's room light

    @cached_property
    def view(self) -> CameraView:
        """The per-camera-pixel geometry (at the pixel centres), computed once."""
        return camera_view(self.sim.rig)

    @cached_property
    def fine_view(self) -> CameraView:
        """The geometry of the sub-pixels rendered (:attr:`view` when ``supersample`` is 1)."""
        if self.supersample == 1:
            return self.view
        return camera_view(self.sim.rig, self.supersample)

    @property
    def shape(self) -> tuple[int, int]:
        """(Hc, Wc) of the camera image."""
        w, h = self.sim.rig.camera.resolution
        return (h, w)

    def _sample(self, grid: np.ndarray) -> np.ndarray:
        """A projector-grid (H, W, 3) array sampled bilinearly at every rendered sub-pixel."""
        return cv2.remap(
            np.ascontiguousarray(grid, np.float32),
            self.fine_view.map_u,
            self.fine_view.map_v,
            cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_REPLICATE,
        )

    def radiance(self, screen: AnyScreen, image: np.ndarray) -> np.ndarray:
        """What leaves the screen toward the camera, per rendered sub-pixel: (k Hc, k Wc, 3)
        float32 linear (k = ``supersample``), before the camera (exposure, vignetting, blur,
        noise).

        ``image`` is the (H, W, 3) uint8 pattern the projector shows.
        """
        eye = self.sim.geometry.camera
        lit = self._lit_sim.radiance(screen, image, eye)
        out = self._sample(lit) * self.fine_view.inside[..., None]
        return out + self._room_light(screen, image, lit)

    def _room_light(self, screen: AnyScreen, image: np.ndarray, lit: np.ndarray) -> np.ndarray:
        """The ambient part of the radiance in camera space (it does not depend on the
        pattern; kept for the last screen)."""
        if self._ambient is None or self._ambient[0] is not screen:
            full = self.sim.radiance(screen, image, self.sim.geometry.camera)
            self._ambient = (screen, self._sample(full - lit))
        return self._ambient[1]

    def linear(self, screen: AnyScreen, image: np.ndarray, vignetting: bool = True) -> np.ndarray:
        """The camera's linear signal before noise and clipping: (Hc, Wc, 3) float32."""
        k = self.supersample
        lin = self.sim.expose(self.radiance(screen, image), vignetting=False)
        if vignetting and self.sim.camera.vignetting:
            lin = lin * self.fine_view.vignette[..., None]
        lin = np.asarray(lin, np.float32)
        if self.blur_px > 0:
            lin = cv2.GaussianBlur(lin, (0, 0), self.blur_px * k, borderType=cv2.BORDER_REFLECT)
        if k > 1:  # each camera pixel: the mean of its k x k sub-pixels
            hc, wc = self.shape
            lin = lin.reshape(hc, k, wc, k, 3).mean(axis=(1, 3), dtype=np.float32)
        return lin

    def capture(self, screen: AnyScreen, image: np.ndarray, key: str) -> np.ndarray:
        """What the camera records: (Hc, Wc, 3) uint8 (uint16 for > 8 bits) encoded values,
        with noise seeded by (sim.seed, ``key``); float32 linear light when the camera
        brackets exposures (:meth:`Simulator.record`)."""
        return self.sim.record(self.linear(screen, image), key)


def geometric_patterns(w: int, h: int) -> dict[str, np.ndarray]:
    """The geometric patterns of a camera-space set, by capture name: ``chessboard``,
    ``graycode_white``, ``graycode_black``, ``graycode_00`` ... (OpenCV's order, each bit plane
    then its inverse, columns then rows), then the phase-shifted sinusoids ``phase_col_0`` ...
    ``phase_row_7`` (:func:`~viewcomp.calib.io.patterns.phase_patterns`). (h, w, 3) uint8
    each."""
    out = {"chessboard": chessboard(w, h)[0]}
    planes, white, black = graycode_patterns(w, h)
    out["graycode_white"] = white
    out["graycode_black"] = black
    digits = max(2, len(str(len(planes) - 1)))
    for k, p in enumerate(planes):
        out[f"graycode_{k:0{digits}d}"] = p
    out.update(phase_patterns(w, h))
    return out


def capture_camera_patterns(
    cam: SimCamera, screen: AnyScreen, black: bool = True, geometric: str = "all"
) -> dict[str, np.ndarray]:
    """Camera-space captures of one screen: Table 1 (and black) plus geometric patterns.

    ``geometric``: ``"all"`` (chessboard, Gray code, phase shifts), ``"chessboard"`` or ``"none"``.
    Returns name -> (Hc, Wc, 3) uint8, in capture order.
    """
    todo = camera_patterns(cam.sim.rig.projector.resolution, black, geometric)
    return {n: cam.capture(screen, img, f"{screen.name}/{n}") for n, img in todo.items()}


def camera_patterns(
    size: tuple[int, int], black: bool = True, geometric: str = "all"
) -> dict[str, np.ndarray]:
    """The patterns of one screen's camera-space captures, in capture order: Table 1 (and
    black) plus ``geometric`` (``"all"``: chessboard, Gray code, phase shifts, ``"chessboard"``,
    ``"none"``), for a projector of ``size`` (W, H). Name -> (H, W, 3) uint8."""
    if geometric not in ("all", "chessboard", "none"):
        raise ValueError(f'geometric must be "all", "chessboard" or "none", got {geometric!r}')
    w, h = size
    pats = table1_patterns(w, h)
    names = [n for n in TABLE1_NAMES if black or n != "black"]
    todo = {n: pats[n] for n in names}
    if geometric != "none":
        geo = geometric_patterns(w, h)
        if geometric == "chessboard":
            geo = {"chessboard": geo["chessboard"]}
        todo.update(geo)
    return todo


def simulate_camera_set(
    out_dir: str | Path,
    screen: str | tuple[float, float, float] | AnyScreen = "magenta",
    gloss: str | tuple[float, float] = "glossy",
    seed: int = 0,
    rig: Rig | None = None,
    black: bool = True,
    *,
    projector: ProjectorPhysics | None = None,
    exposure: float | None = None,
    hdr_stops: tuple[float, ...] | None = None,
) -> list[Path]:
    """Write a camera-space capture set: what the simulated camera records, lens and all.

    white/: Table 1 (and black) and the chessboard on the ideal white screen; screen/: the
    same on the real screen plus the Gray-code captures. The rig.toml says ``space =
    "camera"`` and leaves the lens distortion out (see :func:`written_rig`). ``screen`` is a
    colour (with ``gloss``: :func:`make_screen`) or a screen already made (a measured
    material's); ``projector``, ``exposure`` and ``hdr_stops`` as :func:`camera_simulator`
    (with ``hdr_stops`` the captures are float32 linear ``.npy``). Returns the files.

    Raises:
        SimulatorError: an unknown screen or gloss.
        GeometryError: a rig whose camera does not face the screen.
    """
    true_rig = camera_rig(rig or simulation_rig())
    sim = camera_simulator(true_rig, seed, projector, exposure, hdr_stops)
    cam = SimCamera(sim)
    if isinstance(screen, Screen | MaterialScreen):
        scr = screen
    else:
        scr = make_screen(screen, gloss, shape=sim.shape, seed=seed)
    white = capture_camera_patterns(cam, white_screen(), black, geometric="chessboard")
    real = capture_camera_patterns(cam, scr, black, geometric="all")
    return write_capture_set(out_dir, written_rig(true_rig), white, real)
