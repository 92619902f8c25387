"""The adapted error and the per-pixel physical limit against closed forms."""

from __future__ import annotations

import numpy as np
import pytest

from viewcomp.calib.eval.adapted import adapted_delta_e
from viewcomp.calib.eval.limit import physical_limit
from viewcomp.calib.eval.metrics import delta_e2000
from viewcomp.calib.world.response import Response


def _encode(lin: np.ndarray) -> np.ndarray:
    """sRGB encoding written out here (IEC 61966-2-1), to 8 bits."""
    lin = np.clip(lin, 0.0, 1.0)
    e = np.where(lin <= 0.0031308, 12.92 * lin, 1.055 * lin ** (1 / 2.4) - 0.055)
    return np.rint(e * 255.0).astype(np.uint8)


def _ideal_linear(seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.uniform(0.02, 0.2, (24, 32, 3))


@pytest.mark.parametrize("k", [0.3, 0.5, 2.0, 3.5])
def test_a_uniform_scale_within_two_stops_is_forgiven(k: float) -> None:
    lin = _ideal_linear()
    ideal, seen = _encode(lin), _encode(k * lin)
    got = adapted_delta_e(seen, ideal)
    assert got.scale == pytest.approx(1.0 / k, rel=0.03)
    assert got.de < 0.6  # 8-bit rounding of both images only
    assert delta_e2000(seen, ideal) > 5.0 * got.de + 3.0


@pytest.mark.parametrize("k", [1 / 8, 8.0])
def test_a_scale_beyond_two_stops_is_not(k: float) -> None:
    lin = _ideal_linear(1)
    ideal, seen = _encode(lin), _encode(k * lin)
    got = adapted_delta_e(seen, ideal)
    assert got.scale == pytest.approx(4.0 if k < 1 else 0.25, rel=0.02)
    assert got.de > 5.0
    assert got.de < delta_e2000(seen, ideal)


def test_a_colour_error_is_not_forgiven() -> None:
    lin = _ideal_linear(2)
    tinted = lin * np.array([1.0, 0.6, 0.6])
    got = adapted_delta_e(_encode(tinted), _encode(lin))
    assert got.de > 8.0


def test_limit_of_a_dim_grey_screen() -> None:
    """M = m I, A = 0: within reach (m * 4 >= what the image needs) the limit is ~0; a screen
    too dim even for s = 4 leaves the brightest pixels short."""
    lin = _ideal_linear(3) * 2.0  # up to 0.4
    ideal = _encode(lin)
    srgb = Response("srgb")
    eye3 = np.broadcast_to(np.eye(3), (*lin.shape[:2], 3, 3))
    zero = np.zeros(lin.shape)
    lo, hi = np.zeros(3), np.ones(3)
    ok = physical_limit(0.5 * eye3, zero, lo, hi, ideal, srgb, step=1)
    assert ok.de < 0.5
    dim = physical_limit(0.05 * eye3, zero, lo, hi, ideal, srgb, step=1)
    assert dim.scale == pytest.approx(4.0, rel=0.02)
    assert dim.de > 3.0
    # No drive does better than the limit: the full drive at s = 4 is the brightest there is.
    full = _encode(np.full(lin.shape, 0.05))
    assert adapted_delta_e(full, ideal).de >= dim.de - 0.1


def test_limit_is_below_a_clipped_inverse_on_a_coloured_screen() -> None:
    rng = np.random.default_rng(4)
    lin = rng.uniform(0.05, 0.6, (16, 16, 3))
    ideal = _encode(lin)
    mix = np.broadcast_to(np.diag([0.6, 0.15, 0.1]) + 0.02, (16, 16, 3, 3))
    amb = np.full((16, 16, 3), 0.01)
    srgb = Response("srgb")
    lim = physical_limit(mix, amb, np.zeros(3), np.ones(3), ideal, srgb, step=1)
    light = np.clip(np.linalg.solve(mix, (lin - amb)[..., None])[..., 0], 0.0, 1.0)
    naive = _encode(np.einsum("hwij,hwj->hwi", mix, light) + amb)
    assert lim.de < adapted_delta_e(naive, ideal).de
