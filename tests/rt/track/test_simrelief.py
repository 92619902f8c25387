"""The surfaces photographs are painted on (rt/track/simrelief.py) and how a photograph's ray
finds the surface it sees (simscene.seen_lat): against closed forms."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest

from viewcomp.rt.track.simrelief import MeasuredRelief, Ridge, cylinder
from viewcomp.rt.track.simscene import seen_lat


def bowl(lat: np.ndarray, up: np.ndarray) -> np.ndarray:
    """A smooth face-like surface (IPDs): highest at (0, -0.6), 0.147 there; 0 at the eyes
    (+-0.5, 0), where a relief puts them."""
    return 0.147 - 0.3 * lat**2 - 0.2 * (up + 0.6) ** 2


def sampled(step: float = 0.004) -> np.ndarray:
    """(M, 3) points of :func:`bowl` over lateral +-1, up -1.6..1 (IPDs)."""
    lat, up = np.meshgrid(np.arange(-1.0, 1.0, step), np.arange(-1.6, 1.0, step))
    return np.stack([lat.ravel(), up.ravel(), bowl(lat, up).ravel()], axis=1)


def test_a_measured_relief_keeps_the_surface_it_was_made_of():
    """Made of a surface's points and asked at its own tip (no stretch, no shear), the
    relief is the surface within 0.005 IPD inside it (a cell keeps its most forward point:
    up to a cell's rise, 0.006 on the steepest part here, measured 0.004) and the cylinder
    far outside it."""
    relief = MeasuredRelief.of_surface(sampled(), np.array([0.0, -0.6, 0.147]))
    lat, up = np.meshgrid(np.linspace(-0.8, 0.8, 9), np.linspace(-1.3, 0.7, 9))
    ipd = 0.063
    got = relief.forward(lat * ipd, up * ipd, (0.0, -0.6 * ipd), ipd) / ipd
    np.testing.assert_allclose(got, bowl(lat, up), atol=5e-3)
    far = relief.forward(np.array([1.4]), np.array([1.85]), (0.0, -0.6), 1.0)
    assert far[0] == pytest.approx(cylinder(np.array([1.4]))[0], abs=0.02)


def test_a_measured_relief_puts_its_tip_under_the_photographs():
    """A photograph whose nose tip is 0.2 IPD aside and 0.75 IPD below the eyes: the
    relief's tip (its highest point, 0.147) is there; at the eyes' level nothing moves."""
    relief = MeasuredRelief.of_surface(sampled(), np.array([0.0, -0.6, 0.147]))
    tip = (0.2, -0.75)
    assert relief.forward(np.array([0.2]), np.array([-0.75]), tip, 1.0)[0] == pytest.approx(
        0.147, abs=5e-3
    )
    lat = np.linspace(-0.8, 0.8, 17)
    np.testing.assert_allclose(
        relief.forward(lat, np.zeros_like(lat), tip, 1.0),
        relief.forward(lat, np.zeros_like(lat), (0.0, -0.6), 1.0),
        atol=1e-12,
    )
    # half-way down to the tip: stretched by 0.6 / 0.75, shifted half of the tip's 0.2
    np.testing.assert_allclose(
        relief.forward(lat + 0.1, np.full_like(lat, -0.375), tip, 1.0),
        relief.forward(lat, np.full_like(lat, -0.3), (0.0, -0.6), 1.0),
        atol=1e-9,
    )


def test_a_mirrored_relief_is_the_same_face_reversed():
    pts = sampled()
    pts[:, 2] += 0.1 * pts[:, 0]  # lopsided
    relief = MeasuredRelief.of_surface(pts, np.array([0.1, -0.6, 0.157]))
    np.testing.assert_allclose(
        relief.forward(np.array([-0.5, 0.5]), np.zeros(2), (0.3, -0.6), 1.0), 0.0, atol=1e-12
    )  # levelled: the eyes at depth 0
    mirror = relief.mirrored()
    assert mirror.tip == (-0.1, -0.6)
    lat, up = np.meshgrid(np.linspace(-1.2, 1.2, 13), np.linspace(-2.0, 1.5, 11))
    np.testing.assert_allclose(
        mirror.forward(-lat, up, (-0.05, -0.7), 1.0),
        relief.forward(lat, up, (0.05, -0.7), 1.0),
        atol=1e-12,
    )
    assert Ridge().mirrored() == Ridge()


def test_a_surface_with_no_points_on_the_grid_is_refused():
    with pytest.raises(ValueError, match="no points"):
        MeasuredRelief.of_surface(np.array([[5.0, 5.0, 0.0]]), np.zeros(3))


@dataclass(frozen=True)
class Wall:
    """A thin wall 0.8 IPD high across lateral 0..0.1 (smoothed over 0.005) on flat ground."""

    def forward(self, lat, y, tip, ipd):
        lat = np.asarray(lat, np.float64) / ipd
        rise = 1.0 / (1.0 + np.exp(-lat / 0.005)) / (1.0 + np.exp((lat - 0.1) / 0.005))
        return 0.8 * rise * ipd + 0.0 * np.asarray(y)


def test_a_ray_sees_the_nearer_of_two_surfaces():
    """A photograph taken turned 30 degrees, nose toward the image's right, sees a wall from
    its left: a ray at x = 0.2 meets the wall's left face (lateral about 0) before the ground
    behind it (lateral 0.2 / cos 30 = 0.23); turned the other way, the same ray meets the
    ground (the wall's left face is hidden). A ray past the wall's top reaches the ground;
    one beyond the head's edge meets nothing (NaN)."""
    yaw = math.radians(30.0)
    c, s = math.cos(yaw), math.sin(yaw)
    x = np.array([0.2, 0.8, 2.0])
    y = np.zeros(3)
    lat = seen_lat(Wall(), x, y, (0.0, -0.6), yaw, 1.0)
    assert abs(lat[0]) < 0.03, lat
    fwd = Wall().forward(lat[:2], y[:2], None, 1.0)
    np.testing.assert_allclose(lat[:2] * c + fwd * s, x[:2], atol=1e-7)  # on the ray
    assert lat[1] == pytest.approx(0.8 / c, abs=1e-7)
    assert np.isnan(lat[2])
    other = seen_lat(Wall(), np.array([0.2]), np.zeros(1), (0.0, -0.6), -yaw, 1.0)
    assert other[0] == pytest.approx(0.2 / c, abs=1e-7)
