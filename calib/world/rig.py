"""The rig: projector, camera, viewer and capture settings of rig.toml (docs/INTERFACES.md).

World frame (docs/MODEL.md section 1): metres, the screen is the plane z = 0, +x is the
audience's right, +y is up, +z points from the screen toward the audience.

Devices are pinholes with OpenCV conventions: the device looks along its own +z, image x
points right and image y points down; pixel centres sit at integer coordinates, so the
default principal point is ((w - 1) / 2, (h - 1) / 2) and fx = fy = (h / 2) / tan(fov_y / 2).
"""

from __future__ import annotations

import difflib
import json
import math
import tomllib
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np

from viewcomp.calib.errors import RigError
from viewcomp.calib.world.lens import distort_normalised, undistort_normalised
from viewcomp.calib.world.response import Response, parse_response, table_lines

Vec3 = tuple[float, float, float]
CaptureSpace = Literal["projector", "camera"]

_DEVICE_KEYS = ("resolution", "position", "look_at", "up", "fov_y", "principal_point", "distortion")
_CAMERA_KEYS = (*_DEVICE_KEYS, "response")
_VIEWER_KEYS = ("distance", "height")
_CAPTURE_KEYS = ("space",)
_SECTIONS = {
    "projector": _DEVICE_KEYS,
    "camera": _CAMERA_KEYS,
    "viewer": _VIEWER_KEYS,
    "capture": _CAPTURE_KEYS,
}
_OPTIONAL = {"principal_point", "distortion", "height", "ipd"}
_SPACES = ("projector", "camera")


def unit_rows(v: np.ndarray) -> np.ndarray:
    """v (..., 3) divided by its length: unit vectors, the same bits as dividing by
    ``np.linalg.norm(v, axis=-1)`` (x x + y y + z z in that order), about 3x faster."""
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    return v / np.sqrt(x * x + y * y + z * z)[..., None]


@dataclass(frozen=True, kw_only=True)
class Device:
    """A pinhole projector or camera.

    ``resolution`` (width, height) in pixels; ``position``, ``look_at``, ``up`` in world
    metres; ``fov_y`` the vertical field of view in degrees; ``principal_point`` (cx, cy) in
    pixels or None for the image centre ((w - 1) / 2, (h - 1) / 2); ``distortion`` the OpenCV
    coefficients (k1, k2, p1, p2, k3) or None for none.
    """

    resolution: tuple[int, int]
    position: Vec3
    look_at: Vec3
    up: Vec3
    fov_y: float
    principal_point: tuple[float, float] | None = None
    distortion: tuple[float, float, float, float, float] | None = None

    @property
    def width(self) -> int:
        """Image width in pixels."""
        return self.resolution[0]

    @property
    def height(self) -> int:
        """Image height in pixels."""
        return self.resolution[1]

    def principal(self) -> tuple[float, float]:
        """The effective principal point (cx, cy) in pixels (the default when None)."""
        if self.principal_point is not None:
            return self.principal_point
        w, h = self.resolution
        return ((w - 1) / 2.0, (h - 1) / 2.0)

    def focal(self) -> float:
        """Focal length in pixels: (h / 2) / tan(fov_y / 2), the same for x and y."""
        return (self.height / 2.0) / math.tan(math.radians(self.fov_y) / 2.0)

    def intrinsics(self) -> np.ndarray:
        """The (3, 3) float64 camera matrix K = [[f, 0, cx], [0, f, cy], [0, 0, 1]] (pixels)."""
        f = self.focal()
        cx, cy = self.principal()
        return np.array([[f, 0.0, cx], [0.0, f, cy], [0.0, 0.0, 1.0]], dtype=np.float64)

    def pose(self) -> tuple[np.ndarray, np.ndarray]:
        """World -> device transform: (R (3, 3), t (3,)) float64 with X_dev = R @ X_world + t.

        Rows of R are the device axes in world coordinates: z = normalize(look_at - position)
        (viewing direction), x = normalize(z x up) (image right), y = z x x (image down).
        """
        pos = np.asarray(self.position, dtype=np.float64)
        z = unit_rows(np.asarray(self.look_at, dtype=np.float64) - pos)
        x = unit_rows(np.cross(z, np.asarray(self.up, dtype=np.float64)))
        y = np.cross(z, x)
        rot = np.stack([x, y, z])
        return rot, -rot @ pos

    def _distort(self, xn: np.ndarray, yn: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The device's lens on normalised coordinates (no-op without distortion)."""
        if self.distortion is None:
            return xn, yn
        return distort_normalised(xn, yn, self.distortion)

    def _undistort(self, xd: np.ndarray, yd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Inverse of :meth:`_distort` (no-op without distortion)."""
        if self.distortion is None:
            return xd, yd
        return undistort_normalised(xd, yd, self.distortion)

    def project(self, points: np.ndarray) -> np.ndarray:
        """World points (..., 3) in metres -> pixel coordinates (..., 2) float64 (u right, v down).

        Applies ``distortion`` when set. Points at or behind the device plane (z <= 0 in
        device coordinates) project to NaN.
        """
        pts = np.asarray(points, dtype=np.float64)
        if pts.shape[-1:] != (3,):
            raise ValueError(f"points must have shape (..., 3), got {pts.shape}")
        rot, t = self.pose()
        cam = pts @ rot.T + t
        z = cam[..., 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            safe_z = np.where(z > 0, z, np.nan)
            xn, yn = self._distort(cam[..., 0] / safe_z, cam[..., 1] / safe_z)
        f = self.focal()
        cx, cy = self.principal()
        return np.stack([f * xn + cx, f * yn + cy], axis=-1)

    def pixel_rays(self, h: int | None = None, w: int | None = None) -> np.ndarray:
        """Unit world directions (h, w, 3) float64 of the rays through the pixel centres.

        Pixel (u, v) of the result is array ``[v, u]``, at integer coordinates. Without
        arguments the grid is the device's resolution; another (h, w) samples the same field
        of view on a resampled grid (pixel centre u' maps to u = (u' + 0.5) W / w - 0.5).
        """
        height = self.height if h is None else int(h)
        width = self.width if w is None else int(w)
        if height <= 0 or width <= 0:
            raise ValueError(f"pixel_rays needs a positive grid size, got h={h}, w={w}")
        us = (np.arange(width, dtype=np.float64) + 0.5) * (self.width / width) - 0.5
        vs = (np.arange(height, dtype=np.float64) + 0.5) * (self.height / height) - 0.5
        uu, vv = np.meshgrid(us, vs)
        return self.rays_through(np.stack([uu, vv], axis=-1))

    def rays_through(self, uv: np.ndarray) -> np.ndarray:
        """Unit world directions (..., 3) float64 of the rays through pixels (..., 2) (u, v),
        lens distortion included."""
        p = np.asarray(uv, dtype=np.float64)
        if p.shape[-1:] != (2,):
            raise ValueError(f"uv must have shape (..., 2), got {p.shape}")
        f = self.focal()
        cx, cy = self.principal()
        xn, yn = self._undistort((p[..., 0] - cx) / f, (p[..., 1] - cy) / f)
        dirs_dev = np.stack([xn, yn, np.ones_like(xn)], axis=-1)
        rot, _ = self.pose()
        return unit_rows(dirs_dev @ rot)


@dataclass(frozen=True, kw_only=True)
class Camera(Device):
    """The calibration camera: a :class:`Device` plus its response (``"linear"``, ``"srgb"``,
    a gamma g > 0 or a table, see :mod:`viewcomp.calib.world.response`)."""

    response: str | float | tuple[float, ...]

    def response_curve(self) -> Response:
        """The parsed response curve."""
        return parse_response(self.response)


@dataclass(frozen=True, kw_only=True)
class Viewer:
    """The audience: ``distance`` (m) from the screen centre, eye ``height`` (y, m).

    ``height`` None means the camera's height; a :class:`Rig` resolves it at construction.
    """

    distance: float
    height: float | None = None

    def eye(self, angle_deg: float) -> np.ndarray:
        """Eye position (3,) float64 for viewing angle theta (degrees), docs/MODEL.md section 1:
        E = (d cos theta, h, d sin theta); 90 is straight in front, < 90 the audience's right.
        """
        if self.height is None:
            raise ValueError("viewer height is unresolved; build the Viewer through a Rig")
        from viewcomp.calib.world.eye import eye_from_angle

        return eye_from_angle(angle_deg, self.distance, self.height)


@dataclass(frozen=True, kw_only=True)
class CaptureSpec:
    """``[capture] space``: "projector" (images already on the projector grid) or "camera"
    (raw camera frames, rectified by calibrate)."""

    space: CaptureSpace


@dataclass(frozen=True, kw_only=True)
class Rig:
    """Everything rig.toml says. ``viewer.height`` is filled with the camera's y if None.

    ``tracker`` is the optional ``[tracker]`` section (the camera that follows the audience,
    see :func:`tracking_camera`); None when rig.toml has none. ``tracker_ipd``: its optional
    ``ipd`` key, the viewers' interpupillary distance in metres (None: the tracker's 0.063).
    """

    projector: Device
    camera: Camera
    viewer: Viewer
    capture: CaptureSpec
    tracker: Device | None = None
    tracker_ipd: float | None = None

    def __post_init__(self) -> None:
        if self.viewer.height is None:
            object.__setattr__(
                self, "viewer", replace(self.viewer, height=float(self.camera.position[1]))
            )


def default_rig() -> Rig:
    """The example rig of docs/INTERFACES.md (projector 640x320, camera 1280x720, sRGB)."""
    return Rig(
        projector=Device(
            resolution=(640, 320),
            position=(0.0, -0.03, 0.5),
            look_at=(0.0, 0.0, 0.0),
            up=(0.0, 1.0, 0.0),
            fov_y=20.0,
        ),
        camera=Camera(
            resolution=(1280, 720),
            position=(0.0, 0.035, 0.5),
            look_at=(0.0, 0.0, 0.0),
            up=(0.0, 1.0, 0.0),
            fov_y=30.0,
            response="srgb",
        ),
        viewer=Viewer(distance=0.5, height=0.035),
        capture=CaptureSpec(space="projector"),
    )


# ---------------------------------------------------------------------------------------------
# Parsing and validation


def _fmt(value: Any) -> str:
    """A value as it would look in TOML, for error messages."""
    try:
        return _toml_value(value)
    except TypeError:
        return repr(value)


def _is_number(x: Any) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x)


class _Parser:
    def __init__(self, source: str) -> None:
        self.source = source

    def error(self, section: str, message: str) -> RigError:
        where = f"[{section}] " if section else ""
        return RigError(f"{self.source}: {where}{message}")

    def check_keys(self, section: str, table: Any, allowed: tuple[str, ...]) -> None:
        if not isinstance(table, dict):
            raise self.error("", f"[{section}] must be a table, got {_fmt(table)}")
        unknown = [k for k in table if k not in allowed]
        if unknown:
            hints = []
            for k in unknown:
                close = difflib.get_close_matches(k, allowed, n=1)
                hints.append(f'"{k}"' + (f' (did you mean "{close[0]}"?)' if close else ""))
            raise self.error(
                section,
                f"unknown key{'s' if len(unknown) > 1 else ''} {', '.join(hints)}; "
                f"allowed: {', '.join(allowed)}",
            )
        missing = [k for k in allowed if k not in _OPTIONAL and k not in table]
        if missing:
            raise self.error(
                section, f"missing key{'s' if len(missing) > 1 else ''} {', '.join(missing)}"
            )

    def numbers(self, section: str, key: str, value: Any, n: int, what: str) -> tuple[float, ...]:
        if not (isinstance(value, list) and len(value) == n and all(map(_is_number, value))):
            raise self.error(section, f"{key} must be {what}, got {_fmt(value)}")
        return tuple(float(v) for v in value)

    def vec3(self, section: str, key: str, value: Any) -> Vec3:
        x, y, z = self.numbers(section, key, value, 3, "three numbers [x, y, z] in metres")
        return (x, y, z)

    def device(self, section: str, t: dict[str, Any]) -> dict[str, Any]:
        res = t["resolution"]
        if not (
            isinstance(res, list)
            and len(res) == 2
            and all(isinstance(v, int) and not isinstance(v, bool) and v > 0 for v in res)
        ):
            raise self.error(
                section,
                f"resolution must be two positive integers [width, height], got {_fmt(res)}",
            )
        w, h = int(res[0]), int(res[1])
        position = self.vec3(section, "position", t["position"])
        look_at = self.vec3(section, "look_at", t["look_at"])
        up = self.vec3(section, "up", t["up"])
        fov = t["fov_y"]
        if not (_is_number(fov) and 0.0 < fov < 180.0):
            raise self.error(
                section,
                f"fov_y must be a number of degrees between 0 and 180 (vertical field of view), "
                f"got {_fmt(fov)}",
            )
        view = np.subtract(look_at, position)
        if np.linalg.norm(view) < 1e-12:
            raise self.error(
                section, f"look_at must differ from position, both are {_fmt(list(position))}"
            )
        if np.linalg.norm(np.cross(view / np.linalg.norm(view), up)) < 1e-9:
            raise self.error(
                section,
                f"up must not be parallel to the viewing direction (look_at - position), "
                f"got up = {_fmt(list(up))}",
            )
        out: dict[str, Any] = {
            "resolution": (w, h),
            "position": position,
            "look_at": look_at,
            "up": up,
            "fov_y": float(fov),
        }
        if "principal_point" in t:
            cx, cy = self.numbers(
                section,
                "principal_point",
                t["principal_point"],
                2,
                "two numbers [cx, cy] in pixels",
            )
            out["principal_point"] = (cx, cy)
        if "distortion" in t:
            k = self.numbers(
                section,
                "distortion",
                t["distortion"],
                5,
                "five numbers [k1, k2, p1, p2, k3] (OpenCV order)",
            )
            out["distortion"] = k
        return out

    def rig(self, d: Any) -> Rig:
        if not isinstance(d, dict):
            raise self.error("", f"must be a table of sections, got {_fmt(d)}")
        unknown = [k for k in d if k not in _SECTIONS and k != TRACKER_SECTION]
        if unknown:
            raise self.error(
                "",
                f"unknown section{'s' if len(unknown) > 1 else ''} "
                f"{', '.join('[' + k + ']' for k in unknown)}; allowed: "
                f"{', '.join('[' + k + ']' for k in (*_SECTIONS, TRACKER_SECTION))}",
            )
        missing = [k for k in _SECTIONS if k not in d]
        if missing:
            raise self.error(
                "",
                f"missing section{'s' if len(missing) > 1 else ''} "
                f"{', '.join('[' + k + ']' for k in missing)}",
            )
        for name, allowed in _SECTIONS.items():
            self.check_keys(name, d[name], allowed)

        projector = Device(**self.device("projector", d["projector"]))
        cam = d["camera"]
        try:
            response = parse_response(cam["response"])
        except ValueError as exc:
            raise self.error("camera", f"response: {exc}") from None
        camera = Camera(**self.device("camera", cam), response=response.spec)

        v = d["viewer"]
        dist = v["distance"]
        if not (_is_number(dist) and dist > 0):
            raise self.error(
                "viewer", f"distance must be a positive number of metres, got {_fmt(dist)}"
            )
        height = None
        if "height" in v:
            if not _is_number(v["height"]):
                raise self.error(
                    "viewer", f"height must be a number of metres (eye y), got {_fmt(v['height'])}"
                )
            height = float(v["height"])
        space = d["capture"]["space"]
        if space not in _SPACES:
            raise self.error("capture", f'space must be "projector" or "camera", got {_fmt(space)}')
        return Rig(
            projector=projector,
            camera=camera,
            viewer=Viewer(distance=float(dist), height=height),
            capture=CaptureSpec(space=space),
            tracker=self.tracker(d.get(TRACKER_SECTION)),
            tracker_ipd=self.tracker_ipd(d.get(TRACKER_SECTION)),
        )

    def tracker(self, t: Any) -> Device | None:
        """The optional ``[tracker]`` section: a device with the keys of ``[projector]``."""
        if t is None:
            return None
        self.check_keys(TRACKER_SECTION, t, (*_DEVICE_KEYS, "ipd"))
        return Device(**self.device(TRACKER_SECTION, {k: v for k, v in t.items() if k != "ipd"}))

    def tracker_ipd(self, t: Any) -> float | None:
        """The optional ``[tracker] ipd``: metres, 0.04..0.09 (adults 0.054..0.074)."""
        if t is None or "ipd" not in t:
            return None
        v = t["ipd"]
        if not (_is_number(v) and 0.04 <= v <= 0.09):
            raise self.error(
                TRACKER_SECTION,
                f"ipd is the viewers' interpupillary distance in metres (0.04..0.09, "
                f"typically 0.063), got {_fmt(v)}",
            )
        return float(v)


def rig_from_dict(d: dict[str, Any], source: str = "rig.toml") -> Rig:
    """Validate a parsed rig.toml (a dict of sections) and build the :class:`Rig`.

    ``source`` names the file in error messages. Raises :class:`RigError` for a missing or
    unknown section or key (typos never pass silently) and for a value of the wrong kind.
    """
    return _Parser(source).rig(d)


def tracker_from_dict(t: Any, source: str) -> tuple[Device, float | None]:
    """A ``[tracker]`` table alone (``--tracker FILE.toml``): the camera and its ``ipd`` (m)
    or None, by the rules of rig.toml's section. Raises :class:`RigError` naming ``source``."""
    parser = _Parser(source)
    device = parser.tracker(t)
    assert device is not None  # t is a table here
    return device, parser.tracker_ipd(t)


def load_rig(path: str | Path) -> Rig:
    """Read and validate a rig.toml file. Raises :class:`RigError` naming the file."""
    p = Path(path)
    try:
        text = p.read_bytes().decode("utf-8")
    except FileNotFoundError:
        raise RigError(
            f"{p}: not found - a rig.toml describes projector, camera and viewer "
            "(see docs/INTERFACES.md of viewcomp; `viewcomp simulate` writes an example)"
        ) from None
    except IsADirectoryError:
        raise RigError(f"{p}: is a folder, expected a rig.toml file") from None
    except UnicodeDecodeError as exc:
        raise RigError(f"{p}: not UTF-8 text ({exc})") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise RigError(f"{p}: invalid TOML: {exc}") from None
    return rig_from_dict(data, source=str(p))


# ---------------------------------------------------------------------------------------------
# Writing


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise TypeError(f"cannot write non-finite float {value!r}")
        text = repr(value)
        return text if any(c in text for c in ".en") else text + ".0"
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    raise TypeError(f"cannot write {type(value).__name__} as TOML")


def rig_to_toml(rig: Rig) -> str:
    """rig.toml text for ``rig``; :func:`load_rig` of it gives back an equal :class:`Rig`.

    Optional keys that are None (principal_point, distortion) are left out; the viewer height
    is always written (it is resolved at construction).
    """
    units = {
        "resolution": "width, height (pixels)",
        "position": "metres, world frame",
        "fov_y": "degrees, vertical",
        "principal_point": "pixels",
        "distortion": "k1, k2, p1, p2, k3 (OpenCV order)",
        "response": '"linear", "srgb", g: value = linear^(1/g), or a table',
        "distance": "metres from the screen centre",
        "height": "eye height (y), metres",
        "space": '"projector" or "camera"',
    }
    lines = [
        "# viewcomp rig: every key is described in docs/INTERFACES.md of viewcomp; positions",
        "# are metres in the world frame of its docs/MODEL.md (screen z = 0, +y up, +z toward",
        "# the audience).",
    ]
    for section in _SECTIONS:
        obj = getattr(rig, section)
        lines.append("")
        lines.append(f"[{section}]")
        for f in fields(obj):
            value = getattr(obj, f.name)
            if value is None:
                continue
            if f.name in (
                "position",
                "look_at",
                "up",
                "principal_point",
                "distortion",
                "fov_y",
                "distance",
                "height",
            ):
                value = [float(v) for v in value] if isinstance(value, tuple) else float(value)
            if f.name == "response" and isinstance(value, tuple):  # a table: 8 entries a line
                lines += table_lines(f.name, value, units[f.name], _toml_value)
                continue
            text = f"{f.name} = {_toml_value(value)}"
            if f.name in units:
                text = f"{text:<40} # {units[f.name]}"
            lines.append(text)
    if rig.tracker is not None:
        header = f"{'[' + TRACKER_SECTION + ']':<40} # the webcam that follows the audience"
        lines += ["", header, *_tracker_lines(rig.tracker)]
        if rig.tracker_ipd is not None:
            lines.append(f"ipd = {_toml_value(float(rig.tracker_ipd))}")
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------------------------------------
# The tracking camera: an optional [tracker] section, the webcam that follows the audience


TRACKER_SECTION = "tracker"


def tracking_camera(rig: Rig) -> Device:
    """The camera that follows the audience (``viewcomp track``): ``[tracker]`` if rig.toml has
    one, else ``[camera]`` (the calibration camera, when it is the kiosk's webcam).

    Raises:
        RigError: the chosen camera looks toward the screen (its viewing direction has no
            +z part), so it cannot see a viewer in front of it.
    """
    device: Device = rig.tracker if rig.tracker is not None else rig.camera
    rot, _ = device.pose()
    if rot[2, 2] <= 0.0:
        which = "[tracker]" if rig.tracker is not None else "[camera] (no [tracker] section)"
        raise RigError(
            f"the tracking camera {which} looks toward the screen (look_at - position has no "
            "+z part), so it cannot see the audience; add a [tracker] section with the webcam "
            "that faces the viewers, or give one with --tracker FILE.toml (docs/INTERFACES.md, "
            "rig.toml)"
        )
    return device


def _tracker_lines(device: Device) -> list[str]:
    """The ``[tracker]`` section's ``key = value`` lines (optional keys left out when None)."""
    out = []
    for f in fields(Device):
        value = getattr(device, f.name)
        if value is None:
            continue
        if f.name != "resolution":
            value = [float(v) for v in value] if isinstance(value, tuple) else float(value)
        out.append(f"{f.name} = {_toml_value(value)}")
    return out
