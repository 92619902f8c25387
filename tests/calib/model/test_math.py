"""Each math step against closed forms and round trips (docs/MODEL.md sections 2-4)."""

import numpy as np
import pytest

from viewcomp.calib.comp.tonemap import ToneSmoother, choose_tone_map
from viewcomp.calib.errors import FitError
from viewcomp.calib.fit.paper import (
    fit_phong,
    inverse_lut,
    level_means,
    mixing_from_means,
    regress_rho,
    specular_map,
)
from viewcomp.calib.model.reference import lut_forward, lut_inverse
from viewcomp.calib.sim.simulator import simulation_rig
from viewcomp.calib.world.eye import eye_from_angle
from viewcomp.calib.world.geometry import ScreenGeometry, reflection_vectors

W_TRUE = np.array([[0.70, 0.08, 0.02], [0.06, 0.18, 0.05], [0.01, 0.07, 0.55]])


def _f(level: float) -> np.ndarray:
    return np.full(3, (level / 255.0) ** 2.2)


def _means_from_w(w: np.ndarray, ambient: np.ndarray) -> dict[str, np.ndarray]:
    """Mean captures of Table 1's patterns for C = W f(I) + A (one projector gamma)."""
    out = {}
    for j, name in enumerate(("red", "green", "blue")):
        p = _f(110.0)
        p[j] = _f(130.0)[j]
        out[name] = w @ p + ambient
    out["gray"] = w @ _f(110.0) + ambient
    return out


def test_eq16_with_errata_recovers_column_normalised_w():
    means = _means_from_w(W_TRUE, np.array([0.01, 0.02, 0.015]))
    wt = mixing_from_means(means)
    expected = W_TRUE / np.diag(W_TRUE)[None, :]  # W~ = W D^-1: columns over their diagonal
    np.testing.assert_allclose(wt, expected, rtol=1e-12)
    # The printed Eq. 16 has row 2 col 1 = dL_R[g] / dL_R[b] and row 3 col 1 = 1: both wrong.
    d_r = means["red"] - means["gray"]
    assert not np.isclose(d_r[1] / d_r[2], wt[1, 0])
    assert not np.isclose(1.0, wt[2, 0])


def test_eq16_refuses_a_pattern_not_brighter_in_its_own_channel():
    means = _means_from_w(W_TRUE, np.zeros(3))
    means["green"] = means["gray"].copy()
    with pytest.raises(FitError, match="green"):
        mixing_from_means(means)


def test_w_tilde_recovered_under_noise_from_simulated_captures():
    from tests.support.calibrations import small_simulator
    from viewcomp.calib.sim.simulate import capture_patterns
    from viewcomp.calib.sim.simulator import make_screen

    sim = small_simulator(128, 64, seed=3)
    screen = make_screen("green", "matte")
    raw = capture_patterns(sim, screen)
    lin = {k: sim.response.decode(v / 255.0).astype(np.float64) for k, v in raw.items()}
    wt = mixing_from_means({k: lin[k].reshape(-1, 3).mean(axis=0) for k in lin})
    w = np.asarray(screen.albedo)[:, None] * sim.projector.mixing
    np.testing.assert_allclose(wt, w / np.diag(w)[None, :], atol=0.03)


def test_rho_regression_round_trip():
    levels = np.arange(256) / 255.0
    truth = 0.01 + np.stack([0.3 * levels**2.2, 0.1 * levels**2.0, 0.2 * levels**2.4], 1)
    rho = regress_rho(truth)
    np.testing.assert_allclose(rho, truth, atol=1e-6)
    inv, lo, hi = inverse_lut(rho)
    back = lut_inverse(inv.astype(np.float32), lo, hi, lut_forward(rho, np.arange(256.0)[:, None]))
    np.testing.assert_allclose(back * 255.0, np.repeat(np.arange(256.0)[:, None], 3, 1), atol=0.3)


def test_rho_refuses_flat_and_reversed_ramps():
    levels = np.arange(256) / 255.0
    good = np.stack([levels**2.2] * 3, 1)
    with pytest.raises(FitError, match="flat or decreasing"):
        regress_rho(good[::-1].copy(), "screen/ramp")
    with pytest.raises(FitError, match="flat or decreasing"):
        regress_rho(np.full((256, 3), 0.2), "screen/ramp")
    # Predicted ramps (strict=False) never raise.
    assert np.all(np.diff(regress_rho(good[::-1].copy(), strict=False), axis=0) >= 0)


def test_level_means_of_a_ramp_narrower_than_256():
    cols = np.stack([np.linspace(0, 1, 100)] * 3, 1)
    m = level_means(cols)
    assert m.shape == (256, 3)
    np.testing.assert_allclose(m[:, 0], np.linspace(0, 1, 256), atol=0.01)


def _geometry() -> ScreenGeometry:
    return ScreenGeometry.from_rig(simulation_rig())


def test_reflection_is_the_mirror_of_the_incident_ray():
    g = _geometry()
    y = g.projector - g.pos
    y /= np.linalg.norm(y, axis=-1, keepdims=True)
    r = reflection_vectors(g.pos, g.projector)
    n = np.array([0.0, 0.0, 1.0])
    np.testing.assert_allclose(r, 2 * (y @ n)[..., None] * n - y, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(r, axis=-1), 1.0)


def test_eye_from_angle_conventions():
    np.testing.assert_allclose(eye_from_angle(90, 0.5, 0.035), [0, 0.035, 0.5], atol=1e-12)
    assert eye_from_angle(60, 0.5, 0.0)[0] > 0  # theta < 90 is the audience's right (+x)


def test_phong_fit_recovers_k_and_gamma():
    g = _geometry()
    rv = g.rv(g.camera)
    k, gamma = np.array([0.9, 0.6, 0.4]), np.array([12.0, 30.0, 5.0])
    s = k * rv[..., None] ** gamma
    fit = fit_phong(s, rv, "all")
    np.testing.assert_allclose(fit.ksis, k, rtol=1e-9)
    np.testing.assert_allclose(fit.gamma, gamma, rtol=1e-9)
    row = fit_phong(s, rv, "row", row=rv.shape[0] // 2)
    np.testing.assert_allclose(row.gamma, gamma, rtol=1e-6)


def test_specular_map_removes_vignetting():
    g = _geometry()
    rv = g.rv(g.camera)
    ramp = 0.6 + 0.4 * np.linspace(0, 1, rv.shape[1])[None, :, None]
    vignette = np.broadcast_to(ramp, (*rv.shape, 3))
    spec = 0.5 + 0.5 * np.maximum(rv, 0)[..., None] ** 20
    s90, n = specular_map(0.3 * spec * vignette, 0.8 * vignette)
    ratio = s90 / spec  # vignetting gone: S_90 is the lobe map up to one constant
    np.testing.assert_allclose(ratio, np.broadcast_to(ratio[0, 0], ratio.shape), rtol=1e-9)
    np.testing.assert_allclose(n, (0.3 * spec * vignette).reshape(-1, 3).max(axis=0))


def _brute_tone(u, v, c, lo, hi, lam, mu, scale):
    best = None
    for a in np.round(np.arange(1.0, 0.0999, -0.01), 2):
        for beta in np.linspace(-0.3, 0.3, 1201):
            y = a * u + beta * v + c
            clipped = np.mean((y < lo) | (y > hi))
            cost = clipped + lam * (1 - a) ** 2 + mu * (beta / scale) ** 2
            if best is None or cost < best[0] - 1e-12:
                best = (cost, a, beta)
    return best


@pytest.mark.parametrize("mu", [0.0, 1.0])
def test_tone_map_solver_matches_brute_force(mu):
    rng = np.random.default_rng(7)
    u = rng.uniform(0.0, 1.3, (40, 3))
    v = rng.uniform(0.5, 1.5, (40, 3))
    c = rng.uniform(-0.1, 0.05, (40, 3))
    t = choose_tone_map(u, v, c, 0.0, 1.0, lam=1.0, beta_weight=mu, beta_scale=0.5)
    cost, _, _ = _brute_tone(u, v, c, 0.0, 1.0, 1.0, mu, 0.5)
    assert t.cost <= cost + 1e-9  # exact in beta: never worse than a fine beta grid
    y = t.alpha * u + t.beta * v + c
    assert np.isclose(t.clipped, np.mean((y < -1e-12) | (y > 1 + 1e-12)))


@pytest.mark.parametrize("lam", [0.0, 1.0, 5.0])
def test_tone_map_search_skips_only_alphas_that_cannot_win(lam):
    """The alpha search stops where lam (1 - alpha)^2 alone exceeds the best cost: the pruned
    search picks what evaluating every alpha on its own picks."""
    from viewcomp.calib.comp.tonemap import _best_per_alpha

    rng = np.random.default_rng(11)
    alphas = np.round(np.arange(1.0, 0.0999, -0.05), 2)
    for _ in range(20):
        n = int(rng.integers(5, 400))
        u, v = rng.uniform(-0.2, 1.4, n), rng.uniform(0.0, 1.5, n)
        v[rng.random(n) < 0.1] = 0.0  # some pixel-channels that beta cannot move
        c, lo, hi = rng.normal(0, 0.1, n), np.zeros(n), np.ones(n)
        args = (u, v, c, lo, hi, lam, 3.0, 0.4)
        pruned = _best_per_alpha(alphas, *args)
        every = [_best_per_alpha(np.array([a]), *args)[0] for a in alphas]
        assert pruned == every[: len(pruned)]

        def rank(t):
            return (round(t.cost, 12), -t.alpha)

        assert min(pruned, key=rank) == min(every, key=rank)
        # lam = 0: nothing to prune; here every problem clips ~10 %, so with lam >= 1 the
        # alphas below ~0.6 are skipped.
        assert (len(pruned) == len(alphas)) == (lam == 0)


def _tone_by_counting(alpha, u, v, c, lo, hi, lam, mu, scale):
    """One alpha of the tone-map solver by direct counting: every candidate beta (0, every
    interval end) against every interval, no sorting tricks, no window."""
    from viewcomp.calib.comp.tonemap import BETA_LIMIT, ToneMap

    var = np.abs(v) > 1e-12
    y0 = alpha * u[var] + c[var]
    b1 = np.clip((lo[var] - y0) / v[var], -BETA_LIMIT, BETA_LIMIT)
    b2 = np.clip((hi[var] - y0) / v[var], -BETA_LIMIT, BETA_LIMIT)
    starts, ends = np.minimum(b1, b2), np.maximum(b1, b2)
    y_fixed = alpha * u[~var] + c[~var]
    fixed = np.count_nonzero((y_fixed >= lo[~var]) & (y_fixed <= hi[~var]))
    cand = np.concatenate([[0.0], np.sort(starts), np.sort(ends)])
    inside = ((starts[None, :] <= cand[:, None]) & (cand[:, None] <= ends[None, :])).sum(axis=1)
    clipped = 1.0 - (inside + fixed) / u.size
    cost = clipped + lam * (1.0 - alpha) ** 2 + mu * (cand / scale) ** 2
    ties = cost <= cost.min() + 1e-12
    k = int(np.argmin(np.where(ties, np.abs(cand), np.inf)))
    return ToneMap(alpha, float(cand[k]), float(clipped[k]), float(cost[k]))


@pytest.mark.parametrize("mu", [0.0, 0.5, 3.0])
def test_tone_map_solver_equals_direct_counting(mu):
    """The solver (sorted runs, one merge, a window of betas that can beat beta = 0) gives,
    per alpha, exactly what counting every candidate against every interval gives."""
    from viewcomp.calib.comp.tonemap import _best_per_alpha

    rng = np.random.default_rng(13)
    for trial in range(40):
        n = int(rng.integers(1, 300))
        u, v = rng.uniform(-0.2, 1.4, n), rng.uniform(-0.5, 1.5, n)
        v[rng.random(n) < 0.1] = 0.0  # beta cannot move these
        v[rng.random(n) < 0.05] = 1e-4  # |beta| beyond BETA_LIMIT: clipped
        if trial % 4 == 0:  # many equal ends: ties
            u, v = np.round(u, 1), np.round(v, 1)
        c, lo, hi = rng.normal(0, 0.1, n), rng.uniform(-0.1, 0.1, n), rng.uniform(0.8, 1.2, n)
        scale = float(rng.uniform(0.1, 1.0))
        if trial == 1:
            v[:] = 0.0  # no beta moves anything: only beta = 0 is a candidate
        for alpha in (1.0, 0.9, 0.55):
            got = _best_per_alpha(np.array([alpha]), u, v, c, lo, hi, 1.0, mu, scale)
            assert got == [_tone_by_counting(alpha, u, v, c, lo, hi, 1.0, mu, scale)]


def test_tone_map_is_identity_when_everything_fits():
    u = np.linspace(0.1, 0.9, 30).reshape(10, 3)
    t = choose_tone_map(u, np.ones_like(u), 0.0, 0.0, 1.0)
    assert (t.alpha, t.beta, t.clipped) == (1.0, 0.0, 0.0)


def test_tone_smoother_eases_without_jumps():
    s = ToneSmoother(tau=0.5)
    assert s.update(0.0, 1.0, 0.0) == (1.0, 0.0)
    a, _ = s.update(0.5, 0.5, 0.0)
    assert 0.5 < a < 1.0 and np.isclose(a, 1.0 - 0.5 * (1 - np.exp(-1)))
