"""Measured BRDFs of real materials, evaluated in pure numpy, and a finite projector lens.

A material is a BRDF measured in a gonioreflectometer and stored in the compact neural form of
Sztrajman, Rainer, Ritschel and Weyrich, "Neural BRDF Representation and Importance Sampling"
(Computer Graphics Forum 40(6), 2021): a 6-21-21-3 multilayer perceptron whose six float arrays
``W1 (6, 21) b1 (21,) W2 (21, 21) b2 (21,) W3 (21, 3) b3 (3,)`` are stored in one ``.npz``.
The data is read from a path the user gives (e.g. a folder of measured materials kept next to
the project); none is bundled with this package.

- :func:`load_material` reads and checks one ``.npz`` (never with pickle) into a
  :class:`Material`; a file that cannot be used raises :class:`MaterialError`, naming the file,
  what is wrong and what to do.
- :meth:`Material.brdf` evaluates the BRDF (RGB, per steradian) for incident and outgoing
  directions in the surface's local frame (normal +z); :meth:`Material.reflectance` is
  ``pi * brdf``, the factor relative to a white Lambertian surface.
- :func:`lens_samples` and :func:`lens_averaged_reflectance` model the projector's lens as a
  disk rather than a point: a real highlight is the reflectance averaged over the directions
  from that disk, which blurs the measured one-degree spike.
"""

from __future__ import annotations

import math
import zipfile
from dataclasses import dataclass
from os import PathLike
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from viewcomp.calib.errors import MaterialError

#: The arrays of one material and the shape each must have.
MATERIAL_SHAPES: dict[str, tuple[int, ...]] = {
    "W1": (6, 21),
    "b1": (21,),
    "W2": (21, 21),
    "b2": (21,),
    "W3": (21, 3),
    "b3": (3,),
}

#: Directions evaluated at once by :meth:`Material.brdf`: bounds the temporaries (about 20
#: float64 values of 21 wide per point, some 25 MB a chunk) whatever the number of points.
CHUNK = 1 << 16

#: Largest network output passed to exp: keeps exp finite (float64 overflows past ~709) for
#: weights that are finite but absurd; measured materials stay far below it.
_MAX_LOG = 700.0

#: The golden angle (radians) of the Vogel spiral used by :func:`lens_samples`.
_GOLDEN_ANGLE = math.pi * (3.0 - math.sqrt(5.0))

_FIX = (
    "give the path of a material .npz holding float arrays "
    + ", ".join(f"{key} {shape}" for key, shape in MATERIAL_SHAPES.items())
    + " (scripts/convert_neural_brdf.py of viewcomp's repository writes them from the "
    "published Neural-BRDF weights of MERL, RGL-EPFL and Nielsen 2015 materials)"
)


def _checked(where: str, key: str, value: ArrayLike) -> NDArray[np.float64]:
    """Array ``key`` as a read-only float64 copy, after checking its dtype, shape and values.

    ``where`` names the file (or material) in the error message.
    """
    array = np.asarray(value)
    expected = MATERIAL_SHAPES[key]
    if not (np.issubdtype(array.dtype, np.floating) or np.issubdtype(array.dtype, np.integer)):
        raise MaterialError(
            f"{where}: {key} has dtype {array.dtype}, not a real number type; {_FIX}"
        )
    if array.shape != expected:
        raise MaterialError(f"{where}: {key} has shape {array.shape}, expected {expected}; {_FIX}")
    out = np.array(array, dtype=np.float64)  # a copy: the material owns its arrays
    if not np.all(np.isfinite(out)):
        bad = int(np.count_nonzero(~np.isfinite(out)))
        raise MaterialError(
            f"{where}: {key} has {bad} non-finite value(s) (NaN or inf); the file is damaged, "
            f"{_FIX}"
        )
    out.setflags(write=False)
    return out


@dataclass(frozen=True, eq=False)
class Material:
    """One measured material: the weights of its neural BRDF and a name.

    The arrays are stored as read-only float64 copies (the files hold float32); construction
    checks their shapes (:data:`MATERIAL_SHAPES`) and that every value is finite, raising
    :class:`MaterialError` otherwise. Equality is identity (arrays have no single truth value).

    Attributes:
        name: what the material is called, e.g. the file's stem ``"red-specular-plastic"``.
        W1, b1: first layer, (6, 21) and (21,).
        W2, b2: second layer, (21, 21) and (21,).
        W3, b3: output layer, (21, 3) and (3,): the log of (1 + BRDF) for R, G, B.
    """

    name: str
    W1: NDArray[np.float64]
    b1: NDArray[np.float64]
    W2: NDArray[np.float64]
    b2: NDArray[np.float64]
    W3: NDArray[np.float64]
    b3: NDArray[np.float64]

    def __post_init__(self) -> None:
        where = f"material {self.name!r}"
        for key in MATERIAL_SHAPES:
            # Frozen: the checked copies replace the given arrays through object.__setattr__.
            object.__setattr__(self, key, _checked(where, key, getattr(self, key)))

    def brdf(self, wi: ArrayLike, wo: ArrayLike, *, chunk: int = CHUNK) -> NDArray[np.float64]:
        """The BRDF (RGB, per steradian, >= 0) for light arriving from wi and leaving toward wo.

        Args:
            wi: (..., 3) unit vectors toward the light, in the surface's local frame (normal
                +z, tangent x, binormal y); not renormalised.
            wo: (..., 3) unit vectors toward the viewer, same frame; broadcast against wi.
            chunk: directions evaluated at once (bounds memory, not the result); > 0.

        Returns:
            (..., 3) float64, the broadcast shape of wi and wo with the RGB channels last.
            Zero where wi.z <= 0 or wo.z <= 0 (light or viewer at or below the horizon); NaN
            where an input component is not finite.

        The recipe of the neural BRDF (Sztrajman et al. 2021, isotropic form):

        1. half vector h = normalize(wi + wo); theta_h = atan2(|h.xy|, h.z),
           phi_h = atan2(h.y, h.x);
        2. difference vector d = wi rotated about z by -phi_h, then about y by -theta_h;
        3. x = (sin theta_h, 0, cos theta_h, d.x, d.y, d.z);
        4. y = relu(x W1 + b1); y = relu(y W2 + b2); y = y W3 + b3;
        5. BRDF = max(exp(y) - 1, 0).
        """
        if chunk <= 0:
            raise ValueError(f"chunk must be > 0, got {chunk}")
        wi_arr = np.asarray(wi, dtype=np.float64)
        wo_arr = np.asarray(wo, dtype=np.float64)
        if wi_arr.shape[-1:] != (3,) or wo_arr.shape[-1:] != (3,):
            raise ValueError(
                f"wi and wo must be (..., 3) direction vectors, got shapes {wi_arr.shape} and "
                f"{wo_arr.shape}"
            )
        shape = np.broadcast_shapes(wi_arr.shape, wo_arr.shape)
        # Broadcast views cost no memory; each chunk below is copied out contiguous.
        wi_flat = np.broadcast_to(wi_arr, shape).reshape(-1, 3)
        wo_flat = np.broadcast_to(wo_arr, shape).reshape(-1, 3)
        out = np.empty((wi_flat.shape[0], 3), dtype=np.float64)
        for start in range(0, wi_flat.shape[0], chunk):
            stop = start + chunk
            out[start:stop] = self._brdf_flat(wi_flat[start:stop], wo_flat[start:stop])
        return out.reshape(shape)

    def reflectance(
        self, wi: ArrayLike, wo: ArrayLike, *, chunk: int = CHUNK
    ) -> NDArray[np.float64]:
        """``pi * brdf(wi, wo)``: the radiance toward wo relative to a white Lambertian surface.

        The radiance leaving toward wo from a point lit with irradiance E from wi is
        ``brdf * E``; a Lambertian surface of albedo 1 leaves ``E / pi``. So the radiance is
        ``reflectance * E / pi``: reflectance is the factor relative to a Lambertian white of
        albedo 1, and a Lambertian surface of albedo a has reflectance a in every direction
        (spectralon comes out near 0.94-1.0). Glossy materials exceed 1 near the mirror
        direction (tens to hundreds at the peak).

        Args and shapes as :meth:`brdf`. Returns (..., 3) float64, dimensionless, >= 0.
        """
        return math.pi * self.brdf(wi, wo, chunk=chunk)

    def _brdf_flat(self, wi: NDArray[np.float64], wo: NDArray[np.float64]) -> NDArray[np.float64]:
        """:meth:`brdf` for (n, 3) directions, n <= one chunk."""
        out = np.zeros((wi.shape[0], 3), dtype=np.float64)
        finite = np.all(np.isfinite(wi), axis=1) & np.all(np.isfinite(wo), axis=1)
        out[~finite] = np.nan
        # Above both horizons wi + wo has z > 0, so the half vector is never undefined.
        valid = finite & (wi[:, 2] > 0.0) & (wo[:, 2] > 0.0)
        if not np.any(valid):
            return out
        wi_v = wi[valid]
        h = wi_v + wo[valid]
        h /= np.linalg.norm(h, axis=1, keepdims=True)
        # theta_h = atan2(r, h.z) and phi_h = atan2(h.y, h.x) with r = |h.xy|; h is a unit
        # vector, so sin/cos of both follow without trigonometry (phi_h = 0 where r = 0, as
        # atan2(0, 0) gives).
        r = np.hypot(h[:, 0], h[:, 1])
        sin_t, cos_t = r, h[:, 2]
        safe_r = np.where(r > 0.0, r, 1.0)
        cos_p = np.where(r > 0.0, h[:, 0] / safe_r, 1.0)
        sin_p = np.where(r > 0.0, h[:, 1] / safe_r, 0.0)
        # Rodrigues' rotation of wi about z by -phi_h: v cos a + (z x v) sin a + z (z.v)(1 - cos a)
        # with a = -phi_h reduces to a rotation of (x, y) keeping z.
        x1 = wi_v[:, 0] * cos_p + wi_v[:, 1] * sin_p
        y1 = -wi_v[:, 0] * sin_p + wi_v[:, 1] * cos_p
        z1 = wi_v[:, 2]
        # ... then about y by -theta_h: (y x v) = (v.z, 0, -v.x), so (x, z) rotate keeping y.
        dx = x1 * cos_t - z1 * sin_t
        dz = z1 * cos_t + x1 * sin_t
        x = np.stack([sin_t, np.zeros_like(sin_t), cos_t, dx, y1, dz], axis=1)
        y = np.maximum(x @ self.W1 + self.b1, 0.0)
        y = np.maximum(y @ self.W2 + self.b2, 0.0)
        y = y @ self.W3 + self.b3
        # expm1 is exp(y) - 1 without cancellation near 0.
        out[valid] = np.maximum(np.expm1(np.minimum(y, _MAX_LOG)), 0.0)
        return out


def load_material(path: str | PathLike[str]) -> Material:
    """Read one measured material from an ``.npz`` file (never with pickle).

    Args:
        path: the ``.npz`` holding W1 (6, 21), b1 (21,), W2 (21, 21), b2 (21,), W3 (21, 3),
            b3 (3,) (float32 in the measured set; other keys are ignored).

    Returns:
        the :class:`Material`, named after the file's stem.

    Raises:
        MaterialError: the file is missing, is not an ``.npz`` archive, holds pickled data, or
            lacks a key, or an array has the wrong shape or type or a non-finite value; the
            message names the file, what is wrong and what to do.
    """
    file = Path(path)
    if not file.is_file():
        what = "is a folder, not a file" if file.is_dir() else "does not exist"
        raise MaterialError(f"{file}: {what}; {_FIX}")
    arrays: dict[str, NDArray[np.generic]] = {}
    try:
        loaded = np.load(file, allow_pickle=False)
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        raise MaterialError(
            f"{file}: not an .npz archive that numpy can read without pickle ({exc}); {_FIX}"
        ) from exc
    if not isinstance(loaded, np.lib.npyio.NpzFile):
        raise MaterialError(f"{file}: a single .npy array, not an .npz archive; {_FIX}")
    with loaded:
        missing = [key for key in MATERIAL_SHAPES if key not in loaded.files]
        if missing:
            raise MaterialError(
                f"{file}: missing key(s) {', '.join(missing)} (it has "
                f"{', '.join(loaded.files) or 'none'}); {_FIX}"
            )
        for key in MATERIAL_SHAPES:
            try:
                arrays[key] = loaded[key]
            except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
                raise MaterialError(
                    f"{file}: {key} cannot be read without pickle ({exc}); {_FIX}"
                ) from exc
    checked = {key: _checked(str(file), key, value) for key, value in arrays.items()}
    return Material(name=file.stem, **checked)


def _unit(v: NDArray[np.float64]) -> NDArray[np.float64]:
    """v / |v| along the last axis."""
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def lens_samples(
    center: ArrayLike, axis: ArrayLike, radius_m: float, n: int
) -> NDArray[np.float64]:
    """``n`` deterministic points spread uniformly over the projector's lens, a disk.

    The points follow a Vogel (sunflower) spiral: point k lies at radius
    ``radius_m * sqrt((k + 0.5) / n)`` (the square root makes every point stand for the same
    area, so the points are uniform over the disk) and angle ``k * golden angle``. One point
    (n = 1) is the centre.

    Args:
        center: (3,) the lens centre, world coordinates in metres.
        axis: (3,) the lens's optical axis (any length > 0); the disk is perpendicular to it.
        radius_m: the disk's radius in metres, >= 0 (a lens 1-2 cm across: 0.005-0.01); 0 puts
            every point at the centre.
        n: the number of points, >= 1.

    Returns:
        (n, 3) float64 world points, each at distance <= radius_m from center, in the plane
        through center perpendicular to axis.
    """
    c = np.asarray(center, dtype=np.float64)
    a = np.asarray(axis, dtype=np.float64)
    if c.shape != (3,) or a.shape != (3,):
        raise ValueError(f"center and axis must be (3,), got {c.shape} and {a.shape}")
    norm = float(np.linalg.norm(a))
    if not (np.all(np.isfinite(c)) and np.isfinite(norm) and norm > 0.0):
        raise ValueError(f"center must be finite and axis finite and non-zero, got {c}, {a}")
    if not (math.isfinite(radius_m) and radius_m >= 0.0):
        raise ValueError(f"radius_m must be finite and >= 0, got {radius_m}")
    if n < 1:
        raise ValueError(f"n must be >= 1, got {n}")
    a = a / norm
    # Two unit vectors spanning the disk: the world axis least aligned with the lens axis,
    # made perpendicular to it, and their cross product.
    helper = np.zeros(3)
    helper[int(np.argmin(np.abs(a)))] = 1.0
    u = _unit(helper - a * float(helper @ a))
    v = np.cross(a, u)
    if n == 1:
        return c[None, :].copy()
    k = np.arange(n, dtype=np.float64)
    rho = radius_m * np.sqrt((k + 0.5) / n)
    angle = k * _GOLDEN_ANGLE
    return (
        c
        + (rho * np.cos(angle))[:, None] * u[None, :]
        + (rho * np.sin(angle))[:, None] * v[None, :]
    )


def lens_averaged_reflectance(
    material: Material,
    points: ArrayLike,
    lens_points: ArrayLike,
    eye: ArrayLike,
    *,
    chunk: int = CHUNK,
) -> NDArray[np.float64]:
    """The reflectance at screen points lit through a finite lens and seen from ``eye``.

    The screen is the plane z = 0 with normal +z, so the world frame is the surface's local
    frame. For each screen point p the reflectance is averaged over the lens points l:
    wi = normalize(l - p), wo = normalize(eye - p). Averaging the reflectance is right because
    each lens point carries 1/n of the light reaching p (the lens is small against its distance,
    so the irradiance from each is the same to first order).

    Args:
        material: the screen's material.
        points: (..., 3) screen points in metres, z = 0 (within 1e-6 m).
        lens_points: (n, 3) points on the projector's lens (:func:`lens_samples`), n >= 1.
        eye: (3,) the viewer's (camera's) position in metres.
        chunk: directions evaluated at once by :meth:`Material.brdf`.

    Returns:
        (..., 3) float64 reflectance (dimensionless, >= 0; see :meth:`Material.reflectance`);
        zero where the lens or the eye is at or below the screen's horizon.

    Memory is that of a few copies of ``points``: the lens points are visited one at a time
    and each pass is evaluated in chunks.
    """
    p = np.asarray(points, dtype=np.float64)
    lens = np.asarray(lens_points, dtype=np.float64)
    e = np.asarray(eye, dtype=np.float64)
    if p.shape[-1:] != (3,):
        raise ValueError(f"points must be (..., 3), got shape {p.shape}")
    if lens.ndim != 2 or lens.shape[1] != 3 or lens.shape[0] < 1:
        raise ValueError(f"lens_points must be (n, 3) with n >= 1, got shape {lens.shape}")
    if e.shape != (3,):
        raise ValueError(f"eye must be (3,), got shape {e.shape}")
    if p.size and not np.all(np.abs(p[..., 2]) <= 1e-6):
        raise ValueError(
            "points must lie on the screen plane z = 0 (the local frame's normal is +z); got "
            f"|z| up to {float(np.nanmax(np.abs(p[..., 2])))} m"
        )
    wo = _unit(e - p)
    total = np.zeros(p.shape, dtype=np.float64)
    for lens_point in lens:
        total += material.reflectance(_unit(lens_point - p), wo, chunk=chunk)
    return total / lens.shape[0]
