"""From a face's box in the tracking camera's image to the viewer's eye in the world, and back.

A face seen by a pinhole camera (:class:`viewcomp.calib.world.rig.Device`, OpenCV
conventions) at depth Z along the camera's axis, of physical width W (metres), appears
w = f W / Z pixels wide (f the focal length in pixels). The detector's box gives w, hence
Z = f W / w; the eyes' midpoint sits at a fixed place in the box (centred, ``eye_row`` of its
height from the top), and the ray through that pixel, taken to depth Z, is the eye in the
world frame of docs/MODEL.md (metres, screen plane z = 0, +y up, +z toward the audience).

W is the width of the *detector's box* on a typical adult face (``FACE_WIDTH``, 0.15 m, the
face's width at the cheekbones); a box is square.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from viewcomp.calib.world.rig import Device

FACE_WIDTH = 0.15  # metres: width of the detector's box on a typical adult face
# The eyes' midpoint in a detector box, as a fraction of its height from the top: 0.38 for
# the LBP frontal-face cascade on scikit-image's astronaut (box (173, 64, 101, 101) from
# detectMultiScale(gray, 1.2, 3), eyes at (204, 101) and (246, 104)).
EYE_ROW = 0.38


def camera_for_frames(device: Device, size: tuple[int, int]) -> Device:
    """``device`` as it images frames of ``size`` (w, h) pixels: same field of view.

    A camera that delivers another resolution than rig.toml says (a webcam driver's choice)
    keeps its field of view when the aspect ratio is the same: the focal length and the
    principal point scale with the height.

    Raises:
        ValueError: the aspect ratio differs by more than 1 % (the field of view is then
            unknown); the message names both sizes.
    """
    w, h = (int(v) for v in size)
    rw, rh = device.resolution
    if (w, h) == (rw, rh):
        return device
    if abs((w / h) / (rw / rh) - 1.0) > 0.01:
        raise ValueError(
            f"the camera delivers {w}x{h} frames but rig.toml says {rw}x{rh}, another aspect "
            f"ratio; set the tracking camera's resolution to {w}x{h} (and its fov_y)"
        )
    pp = device.principal_point
    if pp is not None:
        s = h / rh
        pp = ((pp[0] + 0.5) * s - 0.5, (pp[1] + 0.5) * s - 0.5)
    return replace(device, resolution=(w, h), principal_point=pp)


def eyes_from_boxes(
    device: Device,
    boxes: np.ndarray,
    face_width: float = FACE_WIDTH,
    eye_row: float = EYE_ROW,
) -> np.ndarray:
    """Face boxes in the camera's image -> eye positions in the world.

    Args:
        device: the tracking camera (pose, intrinsics, lens) at the frames' resolution.
        boxes: (N, 4) (x, y, w, h) pixels: top-left corner (x right, y down), width and
            height, as OpenCV's detectors return them; w > 0.
        face_width: W, metres, the physical width a box stands for.
        eye_row: the eyes' height in the box, a fraction of h from its top (0..1).

    Returns:
        (N, 3) float64 eye positions, metres, world frame.
    """
    b = np.asarray(boxes, np.float64).reshape(-1, 4)
    if len(b) == 0:
        return np.zeros((0, 3))
    uv = np.stack([b[:, 0] + 0.5 * b[:, 2], b[:, 1] + eye_row * b[:, 3]], axis=-1)
    depth = device.focal() * face_width / b[:, 2]  # along the camera's axis
    rays = device.rays_through(uv)  # (N, 3) unit, world
    rot, _ = device.pose()
    along = rays @ rot[2]  # cosine between each ray and the camera's axis
    return np.asarray(device.position) + rays * (depth / along)[:, None]


def boxes_from_eyes(
    device: Device,
    eyes: np.ndarray,
    face_width: float = FACE_WIDTH,
    eye_row: float = EYE_ROW,
) -> np.ndarray:
    """The inverse of :func:`eyes_from_boxes`: where a face with its eyes at ``eyes`` appears.

    The face is taken parallel to the image plane (a viewer facing the screen, next to which
    the camera sits), so its box is w = f W / Z wide at depth Z.

    Args:
        device: the tracking camera.
        eyes: (N, 3) metres, world frame, in front of the camera.
        face_width, eye_row: as for :func:`eyes_from_boxes`.

    Returns:
        (N, 4) float64 boxes (x, y, w, h) in pixels (h = w); NaN for an eye behind the camera.
    """
    e = np.asarray(eyes, np.float64).reshape(-1, 3)
    rot, t = device.pose()
    depth = (e @ rot.T + t)[:, 2]
    uv = device.project(e)
    with np.errstate(divide="ignore", invalid="ignore"):
        w = np.where(depth > 0, device.focal() * face_width / depth, np.nan)
    return np.stack([uv[:, 0] - 0.5 * w, uv[:, 1] - eye_row * w, w, w], axis=-1)


def distance_from(device: Device, eyes: np.ndarray) -> np.ndarray:
    """(N,) metres from the camera's centre to each eye (N, 3)."""
    e = np.asarray(eyes, np.float64).reshape(-1, 3)
    return np.linalg.norm(e - np.asarray(device.position), axis=-1)
