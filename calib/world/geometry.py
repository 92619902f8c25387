"""Screen geometry on the projector's pixel grid (docs/MODEL.md section 1).

World units are metres; the screen is the plane z = 0 with normal N = (0, 0, 1); +x is the
audience's right, +y up, +z toward the audience. Every per-pixel array here is (H, W, 3) on
the projector grid, row 0 at the top of the projector image.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from viewcomp.calib.errors import GeometryError
from viewcomp.calib.world.rig import Device, Rig, unit_rows

NORMAL = np.array([0.0, 0.0, 1.0])


def meet_screen(origin: np.ndarray, rays: np.ndarray, device: str) -> np.ndarray:
    """Where rays from ``origin`` (3,) metres along ``rays`` (..., 3) meet the screen z = 0.

    The one ray/plane intersection of viewcomp. ``rays`` need not be unit vectors.

    Returns:
        (..., 3) float64 points in metres (z = 0 exactly).

    Raises:
        GeometryError: some ray does not reach the screen in front of ``origin``; the message
            names ``device`` (``"projector"``, ``"camera"``: its rig.toml section).
    """
    o = np.asarray(origin, np.float64)
    d = np.asarray(rays, np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -o[2] / d[..., 2]
    if not np.all(np.isfinite(t)) or np.any(t <= 0):
        raise GeometryError(
            f"some {device} pixels miss the screen plane z = 0: check [{device}] position, "
            f"look_at and fov_y in rig.toml (the {device} must face the screen)"
        )
    pts = o + t[..., None] * d
    pts[..., 2] = 0.0
    return pts


def screen_points(projector: Device) -> np.ndarray:
    """p(x): where each projector pixel's ray meets the screen plane z = 0.

    Returns:
        (H, W, 3) float64 points in metres (z = 0).

    Raises:
        GeometryError: when some pixel's ray does not reach the screen in front of it.
    """
    return meet_screen(np.asarray(projector.position), projector.pixel_rays(), "projector")


def screen_points_at(projector: Device, uv: np.ndarray) -> np.ndarray:
    """Points on the screen z = 0 lit by projector pixels: (..., 2) (u, v) -> (..., 3) metres.

    Raises:
        GeometryError: a ray does not meet the screen in front of the projector.
    """
    return meet_screen(np.asarray(projector.position), projector.rays_through(uv), "projector")


def reflection_vectors(pos: np.ndarray, projector_position: np.ndarray) -> np.ndarray:
    """R(x) = 2 (Y.N) N - Y with Y = normalize(P - p) (Eq. 6). (H, W, 3) unit vectors."""
    y = unit_rows(np.asarray(projector_position, float) - pos)
    r = -y
    r[..., 2] = y[..., 2]
    return r


def view_vectors(pos: np.ndarray, eye: np.ndarray) -> np.ndarray:
    """V(x) = normalize(E - p). (H, W, 3) unit vectors toward the eye."""
    return unit_rows(np.asarray(eye, float) - pos)


def r_dot_v(refl: np.ndarray, pos: np.ndarray, eye: np.ndarray) -> np.ndarray:
    """R.V per pixel, (H, W) float64, in -1..1 (not clamped).

    Computed a block of about 2^18 pixels of rows at a time: the (H, W, 3) float64
    temporaries of a whole 3840x2160 grid would be 200 MB each."""
    refl, pos = np.asarray(refl), np.asarray(pos)
    if refl.ndim != 3:
        return np.sum(refl * view_vectors(pos, eye), axis=-1)
    out = np.empty(refl.shape[:-1])
    step = max(1, (1 << 18) // max(refl.shape[1], 1))
    for r0 in range(0, refl.shape[0], step):
        rows = slice(r0, r0 + step)
        out[rows] = np.sum(refl[rows] * view_vectors(pos[rows], eye), axis=-1)
    return out


def irradiance_falloff(pos: np.ndarray, projector_position: np.ndarray) -> np.ndarray:
    """cos(incidence) / r^2 per pixel, normalised to 1 at the pixel nearest the axis. (H, W)."""
    d = np.asarray(projector_position, float) - pos
    r2 = np.sum(d * d, axis=-1)
    cos_i = d[..., 2] / np.sqrt(r2)
    g = cos_i / r2
    h, w = g.shape
    return g / g[h // 2, w // 2]


@dataclass(frozen=True)
class ScreenGeometry:
    """Per-pixel geometry of a rig: surface points, reflection vectors and the camera eye."""

    pos: np.ndarray  # (H, W, 3) metres
    refl: np.ndarray  # (H, W, 3) unit
    projector: np.ndarray  # (3,) metres
    camera: np.ndarray  # (3,) metres

    @classmethod
    def from_rig(cls, rig: Rig) -> ScreenGeometry:
        """Compute the geometry from a rig (projector pose and intrinsics, camera position)."""
        pos = screen_points(rig.projector)
        proj = np.asarray(rig.projector.position, float)
        if proj[2] <= 0:
            raise GeometryError("[projector] position must be in front of the screen (z > 0)")
        cam = np.asarray(rig.camera.position, float)
        if cam[2] <= 0:
            raise GeometryError("[camera] position must be in front of the screen (z > 0)")
        return cls(pos=pos, refl=reflection_vectors(pos, proj), projector=proj, camera=cam)

    def rv(self, eye: np.ndarray) -> np.ndarray:
        """R.V for an eye at ``eye``: (H, W)."""
        return r_dot_v(self.refl, self.pos, eye)

    def downsample(self, step: int) -> ScreenGeometry:
        """Every ``step``-th pixel in both directions (for fast fits and thumbnails)."""
        return ScreenGeometry(
            self.pos[::step, ::step], self.refl[::step, ::step], self.projector, self.camera
        )
