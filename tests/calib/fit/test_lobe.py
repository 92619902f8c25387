"""The tabulated specular lobe: its coordinate, its lookup, and its fit (calib/model/lobe.py,
calib/fit/lobe.py), against closed forms."""

import numpy as np
import pytest

from viewcomp.calib.fit.lobe import _continue_trend, fit_lobe
from viewcomp.calib.geo.edgezone import edge_zone, fill_edge_zone
from viewcomp.calib.model.lobe import LOBE_N, lobe_lookup, lobe_position
from viewcomp.calib.sim.simulator import simulation_rig
from viewcomp.calib.world.geometry import ScreenGeometry


def _geometry() -> ScreenGeometry:
    return ScreenGeometry.from_rig(simulation_rig())


def _cos_angles(g: ScreenGeometry) -> tuple[np.ndarray, np.ndarray]:
    """cos of the mirror angle (R.V) and of the half-vector angle (N.H) at the camera."""
    v = g.camera - g.pos
    v /= np.linalg.norm(v, axis=-1, keepdims=True)
    y = g.projector - g.pos
    y /= np.linalg.norm(y, axis=-1, keepdims=True)
    h = y + v
    h /= np.linalg.norm(h, axis=-1, keepdims=True)
    return np.sum(g.refl * v, axis=-1), h[..., 2]


def test_position_is_sqrt_one_minus_cos_of_either_angle():
    g = _geometry()
    rv, nh = _cos_angles(g)
    for half, c in ((False, rv), (True, nh)):
        t = lobe_position(g.refl, g.pos, g.camera, half, np.float64)
        np.testing.assert_allclose(t, np.sqrt(np.maximum(1.0 - c, 0.0)), atol=1e-12)
    # At a screen point's mirror direction both angles are zero.
    p = np.zeros((1, 3))
    r = np.array([[0.3, 0.1, np.sqrt(1 - 0.1)]])
    eye = p[0] + 2.0 * r[0]
    for half in (False, True):
        assert lobe_position(r, p, eye, half, np.float64)[0] == pytest.approx(0.0, abs=1e-7)


def test_lookup_interpolates_linearly_and_holds_the_ends():
    table = np.stack([np.linspace(0, 1, 5), np.linspace(2, 1, 5), np.full(5, 0.5)], axis=1)
    np.testing.assert_allclose(lobe_lookup(table, np.linspace(0, 1, 5)), table, atol=1e-12)
    np.testing.assert_allclose(lobe_lookup(table, np.array([0.125]))[0], [0.125, 1.875, 0.5])
    np.testing.assert_allclose(lobe_lookup(table, np.array([-1.0, 3.0])), table[[0, -1]])


def test_fit_recovers_a_phong_lobe_over_the_mirror_angle():
    g = _geometry()
    rv, _ = _cos_angles(g)
    b, kappa, gamma = np.array([0.8, 0.2, 0.15]), np.array([0.35, 0.3, 0.4]), 30.0
    rng = np.random.default_rng(0)
    s = b + kappa * np.maximum(rv, 0)[..., None] ** gamma + rng.normal(0, 0.005, (*rv.shape, 3))
    lobe = fit_lobe(s, g)
    assert lobe.param == "mirror"
    assert np.all(lobe.rms < 0.0075) and np.all(lobe.rms_power_law > 2 * lobe.rms)
    # The baseline is the level of the farthest angles seen, where the true lobe is ~0.
    t_far = lobe.t_seen[1]
    tail = kappa * (1 - t_far**2) ** gamma
    np.testing.assert_allclose(lobe.baseline, b + tail, atol=0.01)
    t = np.linspace(lobe.t_seen[0], lobe.t_seen[1], 50)
    truth = kappa * (1 - t[:, None] ** 2) ** gamma
    np.testing.assert_allclose(lobe.value(t) + lobe.baseline, truth + b, atol=0.015)


def test_fit_prefers_the_half_vector_for_a_microfacet_lobe_and_beats_phong():
    g = _geometry()
    _, nh = _cos_angles(g)
    # A GGX distribution (roughness 0.08) in the half-vector angle: a long tail that no single
    # power of R.V follows.
    a2 = 0.08**2
    ggx = a2 / (np.pi * (nh**2 * (a2 - 1) + 1) ** 2)
    rng = np.random.default_rng(2)
    s = np.array([0.6, 0.3, 0.2]) + 0.02 * ggx[..., None] * np.array([1.0, 1.0, 1.0])
    s = s + rng.normal(0, 0.003, s.shape)
    lobe = fit_lobe(s, g)
    assert lobe.param == "half"
    assert np.all(lobe.rms < 0.5 * lobe.rms_phong)
    assert np.all(lobe.rms < lobe.rms_other)


def test_lobe_beyond_the_seen_angles_falls_to_zero_never_negative():
    g = _geometry()
    rv, _ = _cos_angles(g)
    rng = np.random.default_rng(3)
    s = 0.5 + 0.4 * np.maximum(rv, 0)[..., None] ** 8 + rng.normal(0, 0.004, (*rv.shape, 3))
    lobe = fit_lobe(s, g)
    hi = round(lobe.t_seen[1] * (LOBE_N - 1))
    assert hi < LOBE_N - 100  # the camera sees a small part of the angles
    assert np.all(lobe.table >= 0) and np.all(np.isfinite(lobe.table))
    assert np.all(lobe.table <= lobe.table[: hi + 1].max(axis=0) + 1e-12)
    assert np.all(lobe.table[-1] < 0.01 * lobe.table.max(axis=0) + 1e-12)
    assert np.all(np.diff(lobe.table[hi:], axis=0) <= 1e-12)  # falls monotonically


def test_fit_says_matte_when_there_is_no_lobe():
    g = _geometry()
    rng = np.random.default_rng(1)
    s = np.full((*g.pos.shape[:2], 3), 0.4) + rng.normal(0, 0.004, (*g.pos.shape[:2], 3))
    lobe = fit_lobe(s, g)
    assert np.all(lobe.table == 0) and "matte" in lobe.message
    np.testing.assert_allclose(lobe.baseline, 0.4, atol=0.005)


def test_fit_leaves_out_masked_pixels():
    g = _geometry()
    rv, _ = _cos_angles(g)
    s = 0.5 + 0.4 * np.maximum(rv, 0)[..., None] ** 30 * np.ones(3)
    hot = rv > np.percentile(rv, 99)
    wrecked = s.copy()
    wrecked[hot] = 1.0  # clipped: the capture's top code
    clean = fit_lobe(s, g)
    masked = fit_lobe(wrecked, g, valid=~hot)
    assert masked.masked == np.count_nonzero(hot)
    far = slice(int(masked.t_seen[0] * (LOBE_N - 1)) + 5, None)
    np.testing.assert_allclose(masked.table[far], clean.table[far], atol=0.01)


def _still_falling(g: ScreenGeometry) -> np.ndarray:
    """A GGX lobe (roughness 0.2) in the half-vector angle on a coloured baseline: at the
    frame's farthest angles it is still falling, as measured glossy materials are."""
    _, nh = _cos_angles(g)
    a2 = 0.2**2
    ggx = a2 / (np.pi * (nh**2 * (a2 - 1) + 1) ** 2)
    return np.array([0.5, 0.3, 0.2]) + 0.05 * ggx[..., None] * np.array([1.0, 0.8, 0.6])


def test_the_edge_zone_is_left_out_and_the_curve_continued_over_its_angles():
    """A camera coarser than the projector leaves the frame's outer lines as copies of inner
    values (the edge zone). Fitted as measurements they hold the baseline at the level of
    nearer angles; left out and continued, the baseline is near what a camera that measured
    every pixel reads."""
    g = _geometry()
    s = _still_falling(g)
    # 12 lines of the 640x320 grid: what a 0.6 camera px per projector px webcam leaves
    # (5-6 lines measured at 320x160)
    widths = dict.fromkeys(("top", "bottom", "left", "right"), 12)
    zone = edge_zone(s.shape[:2], widths)
    copied = s.copy()
    fill_edge_zone([copied], widths)
    full = fit_lobe(s, g, param="half")
    as_measured = fit_lobe(copied, g, param="half")
    continued = fit_lobe(copied, g, param="half", filled=zone)
    err_measured = np.abs(as_measured.baseline - full.baseline)
    err_continued = np.abs(continued.baseline - full.baseline)
    assert np.all(err_measured > 0.005 * full.baseline), err_measured  # the bias is visible
    assert np.all(err_continued < 0.25 * err_measured), (err_continued, err_measured)
    assert "edge zone" in continued.message
    # the table over the measured angles is the same curve either way
    lo, hi = (round(v * (LOBE_N - 1)) for v in continued.t_seen)
    np.testing.assert_allclose(
        continued.table[lo:hi] + continued.baseline,
        full.table[lo:hi] + full.baseline,
        atol=0.01,
    )


def test_the_continued_curve_never_rises_nor_drops_below_what_flattened():
    """Over the edge zone's angles the curve continues its trend but never rises (a lobe seen
    rising at its far end is held), and a lobe that has flattened keeps its level."""
    g = _geometry()
    widths = dict.fromkeys(("top", "bottom", "left", "right"), 6)
    zone = edge_zone(g.pos.shape[:2], widths)
    rv, _ = _cos_angles(g)
    flat = 0.5 + 0.4 * np.maximum(rv, 0)[..., None] ** 200 * np.ones(3)
    full = fit_lobe(flat, g, param="mirror")
    copied = flat.copy()
    fill_edge_zone([copied], widths)
    continued = fit_lobe(copied, g, param="mirror", filled=zone)
    np.testing.assert_allclose(continued.baseline, full.baseline, atol=0.002)
    x = np.linspace(0.0, 1.0, 200)
    curves = np.stack([x, 1.0 - 0.99 * x, np.full_like(x, 0.5)], axis=1)
    ahead = _continue_trend(curves, 10)
    assert np.all(ahead[:, 0] == curves[-1, 0])  # rising: held
    assert ahead.shape == (10, 3)
    assert np.all((np.diff(ahead[:, 1]) < 0.0) | (ahead[1:, 1] == 0.0))  # falling ...
    assert ahead[0, 1] < curves[-1, 1] and np.all(ahead[-5:, 1] == 0.0)  # ... never below 0
    np.testing.assert_allclose(ahead[:, 2], 0.5)  # flat: flat
