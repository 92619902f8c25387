"""Rectification's sampling: the camera's density from the map and the reconstruction filter of
a camera coarser than the projector."""

from __future__ import annotations

import numpy as np
import pytest

from viewcomp.calib.geo.projmap import (
    RECONSTRUCTION_SIGMA,
    camera_density,
    reconstruction_sigma,
    rectify,
)


def _maps(density: float, angle: float, size: tuple[int, int] = (160, 90)):
    """remap maps of a camera at ``density`` camera px per projector px, rotated by ``angle``
    radians: projector (u, v) -> camera (x, y)."""
    w, h = size
    uu, vv = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    c, s = np.cos(angle), np.sin(angle)
    x = 20.0 + density * (c * uu - s * vv) + 10.0
    y = 20.0 + density * (s * uu + c * vv) + 10.0
    return x.astype(np.float32), y.astype(np.float32)


@pytest.mark.parametrize("density", [0.6, 1.2, 2.4])
def test_camera_density_reads_the_maps_scale(density: float) -> None:
    assert camera_density(_maps(density, 0.2)) == pytest.approx(density, rel=1e-4)


def test_only_a_camera_coarser_than_the_projector_is_filtered() -> None:
    assert reconstruction_sigma(0.6) == RECONSTRUCTION_SIGMA > 0
    assert reconstruction_sigma(1.0) == reconstruction_sigma(2.4) == 0.0


def test_the_filter_removes_pixel_level_artefacts_and_keeps_broad_shading() -> None:
    maps = _maps(0.6, 0.0)
    yy, xx = np.mgrid[0:120, 0:160].astype(np.float64)
    artefact = 0.05 * ((xx + yy) % 2 * 2 - 1)  # a camera-pixel checker (zipper, block edges)
    shading = 0.2 * np.cos(2 * np.pi * xx / 16.0)  # a period of 16 camera px
    sig = reconstruction_sigma(0.6)
    for what, comp, keep in (("artefact", artefact, 0.02), ("shading", shading, 0.8)):
        img = np.repeat((0.5 + comp)[..., None], 3, axis=2).astype(np.float32)
        plain = rectify(img, maps)[5:-5, 5:-5, 0] - 0.5
        filt = rectify(img, maps, sig)[5:-5, 5:-5, 0] - 0.5
        ratio = float(np.std(filt) / np.std(plain))
        if what == "artefact":
            assert ratio < keep, ratio
        else:
            assert ratio > keep, ratio
        assert filt.shape == (80, 150)
