"""Eye positions: a viewing angle is a shorthand for an eye position (docs/MODEL.md section 1).

The screen is the plane z = 0; the eye at angle theta is E = (d cos theta, h, d sin theta),
theta = 90 straight in front, theta < 90 to the audience's right.
"""

from __future__ import annotations

import numpy as np


def eye_from_angle(theta_deg: float, distance: float, height: float) -> np.ndarray:
    """E_theta = (d cos theta, h, d sin theta): theta = 90 is straight in front, < 90 right.

    Args:
        theta_deg: viewing angle in degrees, 0 < theta < 180 for an eye in front of the screen.
        distance: d, metres from the screen centre.
        height: h, eye height y in metres.

    Returns:
        (3,) float64 eye position in metres.
    """
    t = np.deg2rad(theta_deg)
    return np.array([distance * np.cos(t), height, distance * np.sin(t)])


def angle_of_eye(eye: np.ndarray) -> float:
    """The viewing angle (degrees) whose eye direction in the xz-plane matches ``eye``."""
    return float(np.rad2deg(np.arctan2(eye[2], eye[0])))
