"""The tracking camera (``[tracker]`` of rig.toml): where a rig without one gets it, and how
a file with a ``[tracker]`` table replaces a rig's.

World frame as in :mod:`viewcomp.calib.world.rig`: metres, the screen is z = 0, +x the
audience's right, +y up, +z toward the audience.

A rig written by ``viewcomp simulate`` or ``viewcomp capture`` gets :func:`default_tracker`:
a 1280x720 webcam 90 degrees wide (fov_y 58.716) clipped on the projected picture's top edge
(:data:`ABOVE` metres above it, :data:`FRONT` in front of the screen) and looking at the
``[viewer]`` at 90 degrees (straight in front, at its distance and height). A real kiosk's
webcam is measured and written over it (docs/INTERFACES.md, rig.toml, "measuring the
tracking camera"), or given to ``viewcomp track``/``play`` as ``--tracker FILE.toml``
without recalibrating (:func:`with_tracker_file`).
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import replace
from pathlib import Path

import numpy as np

from viewcomp.calib.errors import GeometryError, RigError
from viewcomp.calib.world.geometry import screen_points_at
from viewcomp.calib.world.rig import (
    TRACKER_SECTION,
    Device,
    Rig,
    tracker_from_dict,
    tracking_camera,
)

WEBCAM_RESOLUTION = (1280, 720)  # pixels: a 720p webcam
WEBCAM_HFOV = 90.0  # degrees, horizontal: a wide conference webcam
ABOVE = 0.03  # metres: the webcam's lens above the picture's top edge
FRONT = 0.02  # metres: the lens in front of the screen plane

_EXAMPLE = (
    "[tracker]",
    "resolution = [1280, 720]",
    "position = [0.0, 0.35, 0.02]",
    "look_at = [0.0, 0.15, 2.0]",
    "up = [0.0, 1.0, 0.0]",
    "fov_y = 58.716",
)


def webcam_fov_y(hfov_deg: float = WEBCAM_HFOV, size: tuple[int, int] = WEBCAM_RESOLUTION) -> float:
    """The vertical field of view (degrees, 3 decimals) of a camera ``hfov_deg`` degrees wide
    with square pixels at ``size`` (w, h): 2 atan(tan(hfov / 2) h / w)."""
    w, h = size
    half = math.atan(math.tan(math.radians(hfov_deg) / 2.0) * h / w)
    return round(2.0 * math.degrees(half), 3)


def picture_top(projector: Device) -> tuple[float, float]:
    """(x, y) metres of the middle of the projected picture's top edge on the screen z = 0;
    (0, 0) when the projector's top row misses the screen (an unusable rig, refused later)."""
    w = projector.resolution[0]
    top = np.array([[-0.5, -0.5], [(w - 1) / 2.0, -0.5], [w - 0.5, -0.5]])
    try:
        pts = screen_points_at(projector, top)
    except GeometryError:
        return (0.0, 0.0)
    return (float(pts[1, 0]), float(np.max(pts[:, 1])))


def default_tracker(rig: Rig) -> Device:
    """A webcam on the picture's top edge looking at the audience (the module's docstring):
    position (x_top, y_top + ABOVE, FRONT), look_at the ``[viewer]``'s eye at 90 degrees."""
    x, y = picture_top(rig.projector)
    eye = rig.viewer.eye(90.0)
    position = (round(x, 4), round(y + ABOVE, 4), FRONT)
    look_at = (round(float(eye[0]), 4), round(float(eye[1]), 4), round(float(eye[2]), 4))
    if look_at[2] <= FRONT + 0.1:  # a viewer at the screen: look straight out instead
        look_at = (position[0], position[1], FRONT + 1.0)
    return Device(
        resolution=WEBCAM_RESOLUTION,
        position=position,
        look_at=look_at,
        up=(0.0, 1.0, 0.0),
        fov_y=webcam_fov_y(),
    )


def with_default_tracker(rig: Rig) -> Rig:
    """``rig`` with :func:`default_tracker` as its ``[tracker]`` when it has none."""
    return rig if rig.tracker is not None else replace(rig, tracker=default_tracker(rig))


def load_tracker_file(path: str | Path) -> tuple[Device, float | None]:
    """The ``[tracker]`` table of a TOML file (``--tracker FILE.toml``; a whole rig.toml
    works too, its other sections are not read): the camera and its optional ``ipd`` (m).

    Raises:
        RigError: the file is missing, not TOML, has no ``[tracker]`` table, or the table
            breaks rig.toml's rules; the message names the file and what to write.
    """
    p = Path(path)
    try:
        data = tomllib.loads(p.read_bytes().decode("utf-8"))
    except (FileNotFoundError, IsADirectoryError):
        raise RigError(
            f"{p}: no such file; --tracker takes a TOML file with a [tracker] table "
            f"(docs/INTERFACES.md, rig.toml), e.g. {'; '.join(_EXAMPLE)}"
        ) from None
    except UnicodeDecodeError as exc:
        raise RigError(f"{p}: not UTF-8 text ({exc})") from None
    except tomllib.TOMLDecodeError as exc:
        raise RigError(f"{p}: invalid TOML: {exc}") from None
    if not isinstance(data.get(TRACKER_SECTION), dict):
        found = ", ".join(f"[{k}]" for k in data) or "nothing"
        raise RigError(
            f"{p}: no [tracker] table (found {found}); write the tracking camera as "
            f"{'; '.join(_EXAMPLE)} (docs/INTERFACES.md, rig.toml)"
        )
    return tracker_from_dict(data[TRACKER_SECTION], source=str(p))


def with_tracker_file(rig: Rig, path: str | Path | None) -> Rig:
    """``rig`` with the tracking camera of ``path`` (:func:`load_tracker_file`) in place of its
    own ``[tracker]``; its ``ipd`` too where the file gives one. None: ``rig`` unchanged."""
    if path is None:
        return rig
    device, ipd = load_tracker_file(path)
    out = replace(rig, tracker=device, tracker_ipd=rig.tracker_ipd if ipd is None else ipd)
    try:
        tracking_camera(out)
    except RigError as exc:
        raise RigError(f"{path}: {exc}") from None
    return out
