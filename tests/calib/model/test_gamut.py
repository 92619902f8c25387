"""The adaptive tone map's per-pixel math: field, reach, knee and the hue-keeping soft clip."""

from __future__ import annotations

import numpy as np
import pytest
from skimage.color import rgb2lab

from viewcomp.calib.model.gamut import (
    KNEE,
    ToneField,
    field_at,
    grey_range,
    knee,
    reach,
    soft_light,
)


def test_field_is_bilinear_between_its_nodes() -> None:
    gain = np.array([[1.0, 2.0], [3.0, 5.0]])
    g, o = field_at(ToneField(gain, np.zeros((2, 2))), (3, 5))
    assert g[0, 0] == 1.0 and g[0, -1] == 2.0 and g[-1, 0] == 3.0 and g[-1, -1] == 5.0
    assert g[1, 2] == pytest.approx((1 + 2 + 3 + 5) / 4)
    assert np.all(o == 0.0)
    g1, _ = field_at(ToneField.uniform(0.7, 0.1, (3, 5)), (8, 9))
    assert np.allclose(g1, 0.7)


def test_reach_of_a_diagonal_screen() -> None:
    m = np.diag([0.5, 0.25, 0.8])[None]
    a = np.array([[0.01, 0.02, 0.03]])
    r = reach(m, a)
    assert np.allclose(r.lowest, a)
    assert np.allclose(r.highest, [[0.51, 0.27, 0.83]])
    # greys n: (n - a_i) / m_ii in [0, 1] for every i -> [max a, min(m_ii + a_i)]
    assert r.grey_lo[0] == pytest.approx(0.03)
    assert r.grey_hi[0] == pytest.approx(0.27)


def test_knee_leaves_what_fits_below_its_top_and_stays_inside() -> None:
    """Everything from lo to the top KNEE of the range passes unchanged (shadows that fit
    are not lifted: in linear light a bottom knee lifted a third of the lightness scale);
    above, the knee bends toward hi without reaching it; below lo, lo."""
    lo, hi = np.float32(0.1), np.float32(2.1)
    x = np.linspace(-2.0, 5.0, 701).astype(np.float32)
    y = knee(x, lo, hi)
    fits = (x >= lo) & (x <= hi - KNEE * (hi - lo))
    assert fits.sum() > 150
    assert np.array_equal(y[fits], x[fits])
    assert np.all(y[x < lo] == lo)
    start = hi - KNEE * (hi - lo)
    top = x > start + 1e-3
    assert np.all((y[top] < x[top]) & (y[top] < hi))
    assert np.all(np.diff(y) >= 0.0)
    # continuous with slope 1 where the knee starts: a small step above it barely bends
    eps = np.float32(1e-3)
    assert knee(start + eps, lo, hi) == pytest.approx(start + eps, abs=2e-5)


def _screen() -> tuple[np.ndarray, np.ndarray]:
    """A reddish screen: green and blue come back weakly."""
    m = np.diag([0.6, 0.2, 0.15]).astype(np.float32) + 0.01
    return m, np.array([0.005, 0.005, 0.005], np.float32)


def _terms(cw: np.ndarray):
    """u, v, c, the grey range and k . C_w of the targets C_w (n, 3) on :func:`_screen`."""
    m, a = _screen()
    m_inv = np.linalg.inv(m.astype(np.float64)).astype(np.float32)
    u = (cw @ m_inv.T).astype(np.float32)
    v = np.broadcast_to(m_inv.sum(axis=-1), u.shape).astype(np.float32)
    c = np.broadcast_to(-(m_inv @ a), u.shape).astype(np.float32)
    lo, hi = grey_range(v, c)
    return u, v, c, lo, hi, cw @ np.array([0.2126, 0.7152, 0.0722], np.float32)


def test_soft_clip_leaves_a_reachable_target_alone() -> None:
    cw = np.array([[0.1, 0.08, 0.06]], np.float32)
    u, v, c, lo, hi, luma = _terms(cw)
    y = soft_light(u, v, c, luma, np.float32([1.0]), np.float32([0.0]), lo, hi)
    assert np.allclose(y, u + c, atol=1e-6)


def test_soft_clip_clips_a_target_below_the_grey_range_per_channel() -> None:
    """A dark target below the lowest grey the screen can show is not lifted to that grey
    (in linear light that lifted shadows by up to a third of the lightness scale): its light
    is the per-channel clip of what it asks for, as the global tone map's."""
    rng = np.random.default_rng(1)
    cw = rng.uniform(0.0, 0.004, (64, 3)).astype(np.float32)
    u, v, c, lo, hi, luma = _terms(cw)
    assert np.all(luma < lo)
    ones, zeros = np.ones(64, np.float32), np.zeros(64, np.float32)
    y = soft_light(u, v, c, luma, ones, zeros, lo, hi)
    assert np.allclose(y, np.clip(u + c, 0.0, 1.0), atol=1e-6)
    assert np.all(y @ np.array([0.2126, 0.7152, 0.0722]) < lo)


def test_hue_weight_is_a_mix_with_the_per_channel_clip() -> None:
    """Weight 0 is the per-channel clip of the light asked for (the global tone map), 1 the
    soft clip, between them the straight mix."""
    rng = np.random.default_rng(2)
    cw = rng.uniform(0.0, 0.6, (64, 3)).astype(np.float32)
    u, v, c, lo, hi, luma = _terms(cw)
    g, o = np.full(64, 1.3, np.float32), np.full(64, 0.01, np.float32)
    asked = np.clip(1.3 * u + 0.01 * v + c, 0.0, 1.0)
    soft = soft_light(u, v, c, luma, g, o, lo, hi)
    assert np.abs(soft - asked).max() > 0.1
    assert np.allclose(soft_light(u, v, c, luma, g, o, lo, hi, 0.0), asked, atol=1e-6)
    mid = soft_light(u, v, c, luma, g, o, lo, hi, 0.25)
    assert np.allclose(mid, 0.75 * asked + 0.25 * soft, atol=1e-6)


def test_soft_clip_keeps_hue_better_than_clipping() -> None:
    """A saturated cyan far beyond what the reddish screen can show: per-channel clipping
    turns its hue; the soft clip gives saturation instead."""
    m, a = _screen()
    rng = np.random.default_rng(0)
    cw = np.column_stack(
        [rng.uniform(0.0, 0.05, 64), rng.uniform(0.3, 0.6, 64), rng.uniform(0.3, 0.6, 64)]
    ).astype(np.float32)
    u, v, c, lo, hi, luma = _terms(cw)
    ones, zeros = np.ones(64, np.float32), np.zeros(64, np.float32)
    soft = soft_light(u, v, c, luma, ones, zeros, lo, hi)
    hard = np.clip(u + c, 0.0, 1.0)
    assert np.all((soft >= 0.0) & (soft <= 1.0))

    def hue(light: np.ndarray) -> np.ndarray:
        shown = light @ m.T + a
        lab = rgb2lab(np.clip(shown / shown.max(), 0, 1)[None])[0]
        return np.arctan2(lab[:, 2], lab[:, 1])

    want = np.arctan2(*rgb2lab(np.clip(cw / cw.max(), 0, 1)[None])[0][:, [2, 1]].T)

    def off(h: np.ndarray) -> float:
        return float(np.mean(np.abs(np.angle(np.exp(1j * (h - want))))))

    assert off(hue(soft)) < 0.5 * off(hue(hard))
