"""The simulator's physics (docs/MODEL.md section 5)."""

import numpy as np
import pytest

from tests.support.calibrations import small_simulator
from viewcomp.calib.eval.testimages import uniform
from viewcomp.calib.sim.simulator import (
    DLP_PROJECTOR,
    PROJECTOR_PRESETS,
    ProjectorPhysics,
    SimulatorError,
    make_screen,
    white_screen,
)
from viewcomp.calib.world.eye import eye_from_angle

W, H = 96, 48


@pytest.fixture(scope="module")
def sim():
    return small_simulator(W, H, seed=5)


def test_matte_screen_looks_the_same_from_every_angle(sim):
    screen = make_screen("red", "matte")
    img = uniform((120, 80, 200), W, H)
    views = [sim.observe_linear(screen, img, eye_from_angle(a, 0.5, 0.035)) for a in (40, 90, 140)]
    np.testing.assert_allclose(views[0], views[1], rtol=1e-12)
    np.testing.assert_allclose(views[2], views[1], rtol=1e-12)


def test_glossy_highlight_moves_with_the_eye(sim):
    screen = make_screen("blue", "glossy")
    img = uniform((110, 110, 110), W, H)
    at90 = sim.lobe(screen, eye_from_angle(90, 0.5, 0.035))
    at60 = sim.lobe(screen, eye_from_angle(60, 0.5, 0.035))
    c90 = np.unravel_index(np.argmax(at90), at90.shape)[1]
    c60 = np.unravel_index(np.argmax(at60), at60.shape)[1]
    assert abs(c90 - W / 2) < W * 0.1  # in front: the highlight is in the middle
    assert c60 > c90 + W * 0.3  # viewer to the right: highlight moves right
    assert (
        sim.observe(screen, img, eye_from_angle(90, 0.5, 0.035)).max()
        > sim.observe(screen, img, eye_from_angle(60, 0.5, 0.035))[:, : W // 2].max()
    )


def test_specular_light_is_white_and_scales_with_the_projected_light(sim):
    screen = make_screen("green", (0.3, 20.0))
    eye = eye_from_angle(90, 0.5, 0.035)
    spec = sim.radiance(screen, uniform((200, 10, 10), W, H), eye) - sim.radiance(
        make_screen("green", "matte"), uniform((200, 10, 10), W, H), eye
    )
    light = sim.light(uniform((200, 10, 10), W, H))
    # The lobe adds k_s (R.V)^n times the light that hits the pixel: the light's colour.
    np.testing.assert_allclose(spec, sim.lobe(screen, eye)[..., None] * light, rtol=1e-12)
    assert spec[H // 2, W // 2, 0] > 5 * spec[H // 2, W // 2, 1]  # red light, red highlight


def test_falloff_is_cos_over_r_squared_and_one_at_the_centre(sim):
    g = sim.geometry
    d = g.projector - g.pos
    r2 = np.sum(d * d, -1)
    expect = (d[..., 2] / np.sqrt(r2)) / r2
    np.testing.assert_allclose(sim.falloff, expect / expect[H // 2, W // 2])
    assert sim.falloff[0, 0] < 0.95


def test_projector_response_crosstalk_ambient_and_quantisation(sim):
    black = sim.radiance(white_screen(), uniform((0, 0, 0), W, H), sim.geometry.camera)
    assert np.all(black > 0)  # ambient and projector leak
    red = sim.light(uniform((255, 0, 0), W, H))
    assert np.all(red[..., 1] > 0.05 * red[..., 0])  # red primary leaks into camera green
    cap = sim.capture(white_screen(), uniform((128, 128, 128), W, H), "k")
    assert cap.dtype == np.uint8 and cap.shape == (H, W, 3)
    f = sim.projector.response(np.array([[0.0, 128.0, 255.0]]).T.repeat(3, 1))
    np.testing.assert_allclose(sim.projector.response_inverse(f), [[0] * 3, [128] * 3, [255] * 3])


def test_vignetting_darkens_the_corners_of_captures_only(sim):
    img = uniform((128, 128, 128), W, H)
    eye = sim.geometry.camera
    cap = sim.expose(sim.radiance(white_screen(), img, eye), vignetting=True)
    eye_view = sim.observe_linear(white_screen(), img, eye)
    assert cap[0, 0, 1] / eye_view[0, 0, 1] < 0.9
    assert np.isclose(cap[H // 2, W // 2, 1] / eye_view[H // 2, W // 2, 1], 1.0, atol=0.01)


def test_seeded_and_reproducible():
    img = uniform((100, 100, 100), W, H)
    a = small_simulator(W, H, seed=1).capture(white_screen(), img, "gray")
    b = small_simulator(W, H, seed=1).capture(white_screen(), img, "gray")
    c = small_simulator(W, H, seed=2).capture(white_screen(), img, "gray")
    np.testing.assert_array_equal(a, b)
    assert np.any(a != c)


def test_screens_and_gloss_presets():
    for name in ("red", "green", "blue", "magenta", "white", "textured"):
        for gloss in ("matte", "satin", "glossy"):
            s = make_screen(name, gloss, shape=(H, W))
            assert s.albedo_map((H, W)).shape == (H, W, 3)
    tex = make_screen("textured", "glossy", shape=(H, W)).albedo_map((H, W))
    assert tex.std(axis=(0, 1)).min() > 0.02
    with pytest.raises(SimulatorError, match="unknown screen"):
        make_screen("purple")
    with pytest.raises(SimulatorError, match=r"0\.\.1"):
        make_screen((1.5, 0.2, 0.2))
    with pytest.raises(SimulatorError, match="unknown gloss"):
        make_screen("red", "shiny")


def test_reflectance_of_analytic_screens_is_albedo_plus_lobe(sim):
    eye = eye_from_angle(70, 0.5, 0.035)
    img = uniform((150, 90, 60), W, H)
    for screen in (make_screen("magenta", "glossy"), make_screen("textured", "satin", (H, W))):
        a = screen.albedo_map(sim.shape)
        refl = a + sim.lobe(screen, eye)[..., None]
        np.testing.assert_array_equal(sim.reflectance(screen, eye), refl)
        np.testing.assert_array_equal(
            sim.radiance(screen, img, eye), refl * sim.light(img) + a * np.asarray(sim.ambient)
        )
        scale = sim.camera.exposure * sim.falloff * sim.vignette
        np.testing.assert_array_equal(
            sim.true_mixing(screen, eye, vignetting=True),
            (refl * scale[..., None])[..., :, None] * sim.projector.mixing,
        )


LEVELS = np.linspace(0.0, 255.0, 2041)[:, None] * np.ones(3)


def test_dlp_response_leak_white_monotone_and_inverse():
    dlp = ProjectorPhysics.dlp()
    assert dlp is DLP_PROJECTOR and PROJECTOR_PRESETS["dlp"] is dlp
    f = dlp.response(LEVELS)
    np.testing.assert_allclose(f[0], [0.025, 0.030, 0.035], rtol=1e-12)
    np.testing.assert_allclose(f[-1], 1.0, rtol=1e-12)
    assert np.all(np.diff(f, axis=0) > 0)
    np.testing.assert_allclose(dlp.response_inverse(f), LEVELS, atol=1e-9)
    light = np.linspace(0.0, 1.0, 999)[:, None] * np.ones(3)
    back = dlp.response(dlp.response_inverse(light))
    np.testing.assert_allclose(back, np.maximum(light, f[0]), atol=1e-12)
    # the leak broadcasts like the response: (3,) against (..., 3)
    assert np.asarray(dlp.leak).shape == (3,)
    assert np.all(dlp.response(LEVELS) >= dlp.leak)


def test_dlp_response_has_a_kink_near_white_and_differs_per_channel():
    dlp = DLP_PROJECTOR
    assert len(set(dlp.gamma)) == 3 and len(set(dlp.kink)) == 3
    for c, (k, s) in enumerate(zip(dlp.kink, dlp.kink_slope, strict=True)):
        assert 0.85 <= k <= 0.9 and 0.4 <= s <= 0.6
        eps = 1e-4
        lv = 255.0 * np.array([[k - 2 * eps, k - eps, k + eps, k + 2 * eps]]).T * np.ones(3)
        f = dlp.response(lv)[:, c]
        below, above = (f[1] - f[0]) / eps, (f[3] - f[2]) / eps
        np.testing.assert_allclose(above / below, s, rtol=1e-3)
    # not a power law: the best power law misses the response by more than a level's worth
    x = LEVELS[1:, 0] / 255.0
    y = (dlp.response(LEVELS)[1:] - np.asarray(dlp.leak)) / (1 - np.asarray(dlp.leak))
    for c in range(3):
        g = np.polyfit(np.log(x[400:]), np.log(y[400:, c]), 1)[0]
        assert np.max(np.abs(x**g - y[:, c])) > 0.02


def test_default_projector_is_the_power_law_and_refuses_bad_kinks():
    p = ProjectorPhysics()
    x = LEVELS / 255.0
    np.testing.assert_array_equal(
        p.response(LEVELS), p.leak + (1.0 - p.leak) * x ** np.asarray(p.gamma)
    )
    np.testing.assert_allclose(p.response_inverse(p.response(LEVELS)), LEVELS, atol=1e-9)
    with pytest.raises(SimulatorError, match="kink"):
        ProjectorPhysics(kink=(0.9, 1.2, 0.9))
    with pytest.raises(SimulatorError, match="kink_slope"):
        ProjectorPhysics(kink=(0.9, 0.9, 0.9), kink_slope=(0.5, 0.0, 0.5))
    with pytest.raises(SimulatorError, match="leak"):
        ProjectorPhysics(leak=(0.1, 0.2))
