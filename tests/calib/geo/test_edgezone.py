"""The edge zone of rectified captures: measured where the surround bleeds in, filled from the
nearest pixel inside it."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter

from viewcomp.calib.geo.edgezone import EDGE_TOL, edge_widths, edge_zone, fill_edge_zone

H, W = 120, 200


def _shaded() -> np.ndarray:
    """A lit frame's true light: a colour with a shading of ~0.4 % a line (vignetting-like)
    and a broad bump, (H, W, 3)."""
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float64)
    shade = 1.0 - 0.4 * ((xx - W / 2) / W) ** 2 - 0.3 * ((yy - H / 2) / H) ** 2
    bump = 0.1 * np.exp(-(((xx - 80) / 40) ** 2 + ((yy - 50) / 30) ** 2))
    return (shade + bump)[..., None] * np.array([0.8, 0.3, 0.6])


def _seen(truth: np.ndarray, sigma: float) -> np.ndarray:
    """The frame as a camera that blurs by ``sigma`` projector px sees it: the dark surround
    (a 20-pixel margin) mixed into its edge, cropped back to the projector grid."""
    pad = np.pad(truth, ((20, 20), (20, 20), (0, 0)))
    return gaussian_filter(pad, (sigma, sigma, 0))[20:-20, 20:-20]


def _line(img: np.ndarray, side: str, n: int) -> np.ndarray:
    """The ``n``-th line (0: outermost) of ``img`` from ``side``."""
    return {"top": img[n], "bottom": img[-n - 1], "left": img[:, n], "right": img[:, -n - 1]}[side]


def test_a_sharp_camera_has_no_zone_beyond_the_floor() -> None:
    assert edge_widths([_shaded()], floor=1) == dict.fromkeys(("top", "bottom", "left", "right"), 1)


@pytest.mark.parametrize("sigma", [1.0, 2.0, 3.0])
def test_the_zone_covers_the_lines_the_blur_darkens(sigma: float) -> None:
    truth = _shaded()
    seen = _seen(truth, sigma)
    widths = edge_widths([seen])
    # outside the zone the seen frame is within a few tolerances of the truth; the zone's
    # innermost line is not far off either (the zone ends where lines stop stepping)
    for side, n in widths.items():
        line, ref = (_line(a, side, n) for a in (seen, truth))
        mid = slice(len(line) // 4, 3 * len(line) // 4)
        off = np.abs(line[mid] / ref[mid] - 1.0).max()
        assert off < 3 * EDGE_TOL, (side, n, off)
    # and a wider blur needs a wider zone
    assert min(widths.values()) >= round(sigma)


def test_the_widest_zone_over_captures_wins() -> None:
    a = edge_widths([_seen(_shaded(), 1.0)])
    b = edge_widths([_seen(_shaded(), 3.0)])
    both = edge_widths([_seen(_shaded(), 1.0), _seen(_shaded(), 3.0)])
    assert both == {k: max(a[k], b[k]) for k in a}


def test_the_corners_take_twice_the_sides() -> None:
    zone = edge_zone((H, W), {"top": 3, "bottom": 2, "left": 4, "right": 1})
    assert zone[:3].all() and zone[-2:].all() and zone[:, :4].all() and zone[:, -1:].all()
    assert zone[5, 7] and not zone[6, 7] and not zone[5, 8]  # top-left square 6 x 8
    assert zone[H - 4, W - 2] and not zone[H - 5, W - 2] and not zone[H - 4, W - 3]
    assert not zone[H // 2, W // 2] and zone.sum() < 0.25 * zone.size


def test_fill_copies_the_nearest_pixel_inside() -> None:
    img = np.arange(H * W, dtype=np.float32).reshape(H, W)
    other = img.copy() * 2
    widths = {"top": 2, "bottom": 3, "left": 1, "right": 2}
    fill_edge_zone([img, other], widths)
    zone = edge_zone((H, W), widths)
    orig = np.arange(H * W, dtype=np.float32).reshape(H, W)
    assert np.array_equal(img[~zone], orig[~zone])  # the inside is untouched
    assert img[0, 50] == orig[2, 50] and img[H - 1, 50] == orig[H - 4, 50]  # sides: line in
    assert img[60, 0] == orig[60, 1] and img[60, W - 1] == orig[60, W - 3]
    # the corner's square (4 x 2 here): (0, 0)'s nearest pixel outside the zone is (2, 2)
    assert zone[3, 1] and not zone[2, 2] and img[0, 0] == orig[2, 2]
    assert np.array_equal(other, img * 2)  # every image gets the same copy


def test_a_zone_without_interior_is_refused() -> None:
    with pytest.raises(ValueError, match="no interior"):
        edge_zone((10, 10), dict.fromkeys(("top", "bottom", "left", "right"), 5))
