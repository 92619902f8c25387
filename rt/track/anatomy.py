"""A viewer's eye from a face's landmarks: distance from the interpupillary distance.

A detector's box is as wide as its training data made it, not as wide as a face; the two eye
centres are a measure of the head itself. Adults' interpupillary distance (IPD) is 63 mm on
average (about +-6 % between people, one standard deviation), so the image separation of the
eyes, s (in normalised units: radians at the eye), gives the range R = IPD cos(yaw) / s from
the camera's centre to the eyes' midpoint.

Per face (five landmarks, pixels: left eye, right eye, nose tip, mouth corners):

1. Each landmark becomes a ray of the tracking camera (its pose, intrinsics and lens:
   :meth:`viewcomp.calib.world.rig.Device.rays_through`); the rays are projected onto the
   plane at unit distance perpendicular to the eyes' midpoint ray m. This removes the
   stretching of an off-axis face in a wide-angle image and the camera's own tilt.
2. Roll (the eye line's angle in that plane) does not shorten the eyes' separation: the full
   2-D distance s between the eyes is used, and the nose is measured along the eye line.
3. Yaw (the head turned about its vertical axis) shortens s by cos(yaw) and moves the nose
   tip, which stands ``nose_depth`` IPD in front of the eyes, sideways by
   nose_depth IPD sin(yaw): with r = (nose - eyes' midpoint) . eye direction / s,
   tan(yaw) = r / nose_depth and cos(yaw) = 1 / sqrt(1 + tan(yaw)^2). Pitch (nodding) moves
   the nose across the eye line and does not change s.
4. The eye (the eyes' midpoint) is the camera's centre + R m, in the world frame.

Error model (docs/INTERFACES.md): the range is proportional to the viewer's true IPD, so a
person whose IPD differs from ``ipd`` by 6 % is ranged 6 % off (x, y scale with it along the
line of sight); a landmark error of e pixels on an eye separation of S pixels gives about
e sqrt(2) / S; a real nose depth 20 % smaller than ``nose_depth`` under-reads the yaw and
ranges 5 % far at 30 degrees of yaw, 10 % at 45. The head is taken as flat across the line
of sight (the near eye's perspective is ignored): within 1.5 % up to 25 degrees, 3 % at 45.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from viewcomp.calib.world.rig import Device

IPD = 0.063  # metres: mean adult interpupillary distance
# The nose tip's depth in front of the pupils, as a fraction of the IPD (about 25 mm).
NOSE_DEPTH = 0.4
MAX_YAW = np.radians(60.0)  # a larger estimate is clipped (a nearly profile face)


@dataclass
class HeadPose:
    """What the landmarks of N faces say: ``eyes`` (N, 3) metres, world frame (the eyes'
    midpoint); ``range`` (N,) metres from the camera's centre; ``yaw`` and ``roll`` (N,)
    radians (yaw positive when the nose points to the image's right); ``separation`` (N,)
    the eyes' separation in normalised units (radians)."""

    eyes: np.ndarray
    range: np.ndarray
    yaw: np.ndarray
    roll: np.ndarray
    separation: np.ndarray


def head_pose(
    device: Device,
    landmarks: np.ndarray,
    ipd: float = IPD,
    nose_depth: float = NOSE_DEPTH,
) -> HeadPose:
    """Eye positions from face landmarks.

    Args:
        device: the tracking camera at the frames' resolution.
        landmarks: (N, 5, 2) pixels (x right, y down): the eye on the image's left, the eye
            on its right, the nose tip, the mouth corners (YuNet's order; the mouth is not
            used). (N, 2, 2) (eyes only) is taken as a frontal face.
        ipd: the viewer's interpupillary distance, metres (> 0).
        nose_depth: the nose tip's depth in front of the eyes, a fraction of ``ipd``.

    Returns:
        :class:`HeadPose` of the N faces.
    """
    if not ipd > 0:
        raise ValueError(f"the interpupillary distance must be > 0 metres, got {ipd}")
    lm = np.asarray(landmarks, np.float64)
    if lm.ndim != 3 or lm.shape[2] != 2 or lm.shape[1] < 2:
        raise ValueError(f"landmarks must have shape (N, 5, 2) or (N, 2, 2), got {lm.shape}")
    n = len(lm)
    if n == 0:
        z = np.zeros(0)
        return HeadPose(np.zeros((0, 3)), z, z, z, z)
    rays = device.rays_through(lm)  # (N, K, 3) unit, world
    m = rays[:, 0] + rays[:, 1]
    m /= np.linalg.norm(m, axis=1, keepdims=True)
    # a frame (a, b, m) per face: a is the camera's x axis made perpendicular to m
    rot, _ = device.pose()
    a = rot[0] - (m @ rot[0])[:, None] * m
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    b = np.cross(m, a)
    on_plane = rays / np.sum(rays * m[:, None, :], axis=2, keepdims=True)  # unit distance
    q = np.stack([np.sum(on_plane * a[:, None], 2), np.sum(on_plane * b[:, None], 2)], -1)
    d = q[:, 1] - q[:, 0]
    sep = np.linalg.norm(d, axis=1)
    along = d / sep[:, None]
    roll = np.arctan2(along[:, 1], along[:, 0])
    if lm.shape[1] >= 3:
        r = np.sum((q[:, 2] - 0.5 * (q[:, 0] + q[:, 1])) * along, axis=1) / sep
        yaw = np.clip(np.arctan2(r, nose_depth), -MAX_YAW, MAX_YAW)
    else:
        yaw = np.zeros(n)
    rng = ipd * np.cos(yaw) / sep
    eyes = np.asarray(device.position, np.float64) + m * rng[:, None]
    return HeadPose(eyes, rng, yaw, roll, sep)


def landmarks_of_head(
    device: Device,
    eyes: np.ndarray,
    yaw: np.ndarray | float = 0.0,
    ipd: float = IPD,
    nose_depth: float = NOSE_DEPTH,
) -> np.ndarray:
    """The inverse of :func:`head_pose` (tests): where the eyes and the nose tip of heads with
    their eyes' midpoint at ``eyes`` (N, 3) metres appear, each head facing the camera's
    centre, upright, turned by ``yaw`` radians (N,) about the vertical; (N, 3, 2) pixels."""
    e = np.asarray(eyes, np.float64).reshape(-1, 3)
    yw = np.broadcast_to(np.asarray(yaw, np.float64), (len(e),))
    out = np.empty((len(e), 3, 2))
    for i, (p, t) in enumerate(zip(e, yw, strict=True)):
        back = np.asarray(device.position, np.float64) - p  # from the head to the camera
        back /= np.linalg.norm(back)
        side = np.cross(np.array([0.0, 1.0, 0.0]), back)
        side /= np.linalg.norm(side)
        up = np.cross(back, side)
        c, s = np.cos(t), -np.sin(t)  # positive: the nose toward the image's right
        side_t, back_t = c * side + s * back, c * back - s * side
        pts = np.stack(
            [
                p - 0.5 * ipd * side_t,
                p + 0.5 * ipd * side_t,
                p + nose_depth * ipd * back_t - 0.5 * ipd * up,
            ]
        )
        out[i] = device.project(pts)
    return out
