"""A face seen square-on: a crop of a frame as a virtual camera pointed at the face.

A wide-angle camera stretches what lies off its axis: a face at angle t from the axis is
imaged 1/cos t wider along the radius than across it (1.4 at the edge of a 90-degree
webcam), and a detector trained on faces in the middle of photographs misplaces the
landmarks of a stretched one (in plain crops YuNet ranged frontal faces 25-60 degrees aside
1-4 % farther than faces in the middle, median, one person's up to 9 %; docs/INTERFACES.md).
A :class:`View` is a pinhole camera at the tracking
camera's centre whose axis passes through the face, with the camera's roll: its image is
the frame resampled along the same rays (lens distortion included), so the face is seen as
if in the middle of the picture, at the scale asked; its pixels map back to the frame's
along the same rays, so the landmarks found in it are frame pixels again for
:func:`viewcomp.rt.track.anatomy.head_pose`.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from viewcomp.calib.world.rig import Device

# The resampling map is computed on a grid this many view pixels apart and interpolated
# (the rays' map is smooth: a few thousand projections instead of a few hundred thousand).
STEP = 8


@dataclass
class View:
    """A virtual camera at ``device``'s centre: ``axes`` (3, 3) rows x (right), y (down), z
    (its axis), world; ``focal`` pixels; ``size`` pixels square, its centre on the axis."""

    device: Device
    axes: np.ndarray
    focal: float
    size: int

    @classmethod
    def of_box(cls, device: Device, box: np.ndarray, width_px: float, context: float) -> View:
        """The view whose axis passes through the centre of ``box`` (x, y, w, h frame
        pixels), at a scale that makes the box ``width_px`` pixels wide (its width measured
        as the angle between the rays through its left and right edges), ``context`` box
        sizes (the larger of width and height) each side of the centre."""
        x0, y0, w, h = (float(v) for v in box[:4])
        cx, cy = x0 + w / 2.0, y0 + h / 2.0
        z, left, right = device.rays_through(np.array([[cx, cy], [x0, cy], [x0 + w, cy]]))
        rot, _ = device.pose()
        x = rot[0] - (z @ rot[0]) * z  # the camera's right, made perpendicular to the axis
        x /= np.linalg.norm(x)
        y = np.cross(z, x)  # down, as the camera's own y
        angle = float(np.arccos(np.clip(left @ right, -1.0, 1.0)))
        focal = width_px / (2.0 * np.tan(max(angle, 1e-6) / 2.0))
        side = 2.0 * context * width_px * max(w, h) / max(w, 1.0)
        size = STEP * max(1, round(side / STEP))
        return cls(device, np.stack([x, y, z]), float(focal), size)

    def rays(self, uv: np.ndarray) -> np.ndarray:
        """World directions (..., 3) (not unit) through view pixels ``uv`` (..., 2)."""
        c = (self.size - 1) / 2.0
        p = (np.asarray(uv, np.float64) - c) / self.focal
        return p[..., :1] * self.axes[0] + p[..., 1:2] * self.axes[1] + self.axes[2]

    def to_frame(self, uv: np.ndarray) -> np.ndarray:
        """Frame pixels (..., 2) of view pixels ``uv`` (..., 2), along the same rays."""
        return self.device.project(np.asarray(self.device.position) + self.rays(uv))

    def homography(self) -> np.ndarray:
        """(3, 3): view pixels -> frame pixels, for a device without lens distortion (a
        pinhole camera turned about its centre: K R A, A the view's pixels -> rays)."""
        c = (self.size - 1) / 2.0
        x, y, z = self.axes
        a = np.stack([x / self.focal, y / self.focal, z - c * (x + y) / self.focal], axis=1)
        rot, _ = self.device.pose()
        return self.device.intrinsics() @ rot @ a

    def image(self, frame: np.ndarray) -> np.ndarray:
        """The view of ``frame`` ((h, w, ...) uint8, the device's resolution): (size, size,
        ...) bilinear, black beyond the frame. Without lens distortion the map is a
        homography (one warp); with it, the rays' map on a grid, interpolated."""
        size = (self.size, self.size)
        if self.device.distortion is None:
            flags = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
            return cv2.warpPerspective(frame, self.homography(), size, flags=flags)
        n = self.size // STEP
        # grid points where cv2.resize puts the samples of an n-point row it stretches to
        # `size` pixels, so the interpolated map is the exact one at them
        g = (np.arange(n, dtype=np.float64) + 0.5) * STEP - 0.5
        uu, vv = np.meshgrid(g, g)
        src = self.to_frame(np.stack([uu, vv], axis=-1)).astype(np.float32)
        src = np.nan_to_num(src, nan=-1e4)  # behind the camera: outside the frame
        mx = cv2.resize(src[..., 0], size, interpolation=cv2.INTER_LINEAR)
        my = cv2.resize(src[..., 1], size, interpolation=cv2.INTER_LINEAR)
        return cv2.remap(frame, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)
