"""The bundle's compact per-pixel maps (viewcomp.calib.io.compact): the error bound holds."""

from __future__ import annotations

import numpy as np
import pytest

from viewcomp.calib.io.compact import (
    MIX_REL_TOL,
    REL_TOL,
    decode_map,
    decode_screen,
    encode_map,
    encode_screen,
)


def _field(rng: np.random.Generator, h: int, w: int, c: int, noise: float) -> np.ndarray:
    """A smooth positive field (H, W, C) plus relative noise."""
    y, x = np.mgrid[0:h, 0:w] / max(h, w)
    base = 0.5 + 0.3 * np.sin(3 * x[..., None] + np.arange(c)) * np.cos(2 * y[..., None])
    return (base * (1 + noise * rng.standard_normal((h, w, c)))).astype(np.float32)


@pytest.mark.parametrize("predict", [True, False])
def test_map_round_trip_within_the_bound(predict: bool) -> None:
    rng = np.random.default_rng(1)
    a = _field(rng, 37, 53, 4, 1e-2)
    a[3, 5, 1] = -0.2  # a negative value and a wide one
    a[7, 9, 2] = 400.0
    planes, step = encode_map(a, REL_TOL, predict)
    assert planes.dtype == np.uint8 and planes.shape == (4, 37, 53, 4)
    back = decode_map(planes, step, a.shape)
    assert back.dtype == np.float32
    bound = REL_TOL * np.median(np.abs(a), axis=(0, 1))
    err = np.abs(back.astype(np.float64) - a).max(axis=(0, 1))
    # half a step plus float32's rounding of the value itself
    assert np.all(err <= bound * 1.0001 + np.abs(a).max(axis=(0, 1)) * 2**-24)
    assert np.all(err > 0)  # lossy: the test would see a wrong step or predictor


def test_map_without_a_scale_or_too_wide_keeps_float32() -> None:
    a = np.zeros((5, 6, 2), np.float32)
    a[..., 1] = 1e-3
    a[0, 0, 1] = 3e9  # median 1e-3: the integers would not fit int32
    planes, step = encode_map(a)
    assert np.all(step == 0)
    np.testing.assert_array_equal(decode_map(planes, step, a.shape), a)


def test_decode_refuses_what_does_not_fit() -> None:
    planes, step = encode_map(np.ones((4, 5, 3), np.float32))
    with pytest.raises(ValueError):
        decode_map(planes, step, (4, 6, 3))
    with pytest.raises(ValueError):
        decode_map(planes, np.array([np.nan, 1.0, 1.0]), (4, 5, 3))


def test_screen_round_trip_within_the_bound() -> None:
    rng = np.random.default_rng(2)
    h, w = 29, 41
    gain = _field(rng, h, w, 3, 2e-2)
    mix = 0.1 * _field(rng, h, w, 9, 0.0).reshape(h, w, 3, 3)
    for i in range(3):
        mix[..., i, i] = 1.0
    wmap = mix * gain[..., None, :]
    amb = 0.02 * _field(rng, h, w, 3, 0.0)
    arrays = dict(encode_screen("w", wmap, amb))
    assert {k for k in arrays if not k.endswith("_step")} == {
        "pixel.Ww.gain",
        "pixel.Ww.mix",
        "pixel.Aw",
    }
    w2, a2 = decode_screen(arrays, "w")
    # W2_ij = mix2_ij gain2_j: the gain's bound times |mix_ij| plus the mixing's bound times
    # |gain_j|, per pixel (mix_ii = 1, exact), plus float32 rounding.
    gain_tol = REL_TOL * np.median(gain, axis=(0, 1))
    mix_tol = MIX_REL_TOL * np.median(np.abs(mix), axis=(0, 1))
    np.fill_diagonal(mix_tol, 0.0)
    bound = np.abs(mix) * gain_tol + (np.abs(gain) + gain_tol)[..., None, :] * mix_tol
    err = np.abs(w2.astype(np.float64) - wmap)
    assert np.all(err <= bound * 1.0001 + np.abs(wmap) * 2**-22)
    a_err = np.abs(a2.astype(np.float64) - amb)
    assert np.all(a_err <= REL_TOL * np.median(amb, axis=(0, 1)) * 1.0001 + amb * 2**-23)
