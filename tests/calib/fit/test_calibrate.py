"""Calibration from captures, the bundle, and compensation closed-loop in the simulator."""

import shutil

import numpy as np
import pytest

from tests.support.calibrations import small_calibration, small_simulator
from viewcomp.calib.comp.compensation import Compensation
from viewcomp.calib.errors import FitError
from viewcomp.calib.eval.metrics import sse
from viewcomp.calib.eval.testimages import uniform
from viewcomp.calib.fit.calibrate import Calibration, calibrate
from viewcomp.calib.io.bundle import BundleError
from viewcomp.calib.io.captureset import capture_set_from_raw, read_capture_set
from viewcomp.calib.io.imageio import read_image, write_png
from viewcomp.calib.model.reference import lobe_change, target_to_projector
from viewcomp.calib.sim.simulate import capture_patterns, simulate_capture_set
from viewcomp.calib.sim.simulator import make_screen, white_screen
from viewcomp.calib.world.eye import eye_from_angle

W, H = 128, 64


@pytest.fixture(scope="module")
def world():
    sim = small_simulator(W, H, seed=4)
    screen = make_screen("magenta", "glossy", shape=sim.shape)
    white = capture_patterns(sim, white_screen())
    real = capture_patterns(sim, screen)
    cal = calibrate(capture_set_from_raw(sim.rig, white, real))
    return sim, screen, white, real, cal


def test_per_pixel_fits_recover_the_simulators_truth(world):
    sim, screen, _, _, cal = world
    assert cal.info["colour_guide_px"] == 0  # a projector-space set: the mixing per pixel
    lobe = cal.pixel.lobe
    # The lobe's change from the camera to an eye, as the simulator's Phong lobe makes it
    # (relative to the white screen's albedo 0.85).
    g = cal.pixel.geometry
    for angle in (60, 120):
        eye = eye_from_angle(angle, 0.5, 0.035)
        truth = (
            screen.k_s
            / 0.85
            * (
                np.maximum(g.rv(eye), 0) ** screen.shininess
                - np.maximum(g.rv(g.camera), 0) ** screen.shininess
            )
        )
        est = lobe.at(g, eye) - lobe.at(g, g.camera)
        np.testing.assert_allclose(est, truth[..., None] * np.ones(3), atol=0.04)
    truth = sim.true_mixing(screen, sim.geometry.camera, vignetting=True)
    # W_c(x) f = M(x) f_true: compare the colour mixing up to the projector's scale.
    # Each column j is known up to the scale of f_j's normalisation: compare per column.
    for c in ((H // 2, W // 2), (H // 4, W // 5)):
        est, tru = cal.pixel.screen.W[c], truth[c]
        scaled = est * (np.diag(tru) / np.diag(est))[None, :]
        np.testing.assert_allclose(scaled, tru, atol=0.03 * np.abs(tru).max())


def test_per_pixel_compensation_closes_the_loop_where_reachable(world):
    sim, screen, _, _, cal = world
    comp = Compensation(cal, "pixel")
    image = uniform((100, 60, 90), W, H)
    for angle in (60, 90, 120):
        eye = eye_from_angle(angle, 0.5, 0.035)
        out, p = comp.compensate_image(image, eye)
        assert p.alpha == 1.0 and abs(p.beta) < 1e-9  # reachable: no tone map needed
        ideal = sim.observe(white_screen(), image, eye)
        seen = sim.observe(screen, out, eye)
        assert np.mean(np.abs(seen.astype(int) - ideal)) < 1.5  # within ~1 level on average
        assert sse(seen, ideal) < 0.05 * sse(sim.observe(screen, image, eye), ideal)


def test_per_pixel_solve_is_the_limit_of_the_fixed_point_feedback(world):
    """docs/MODEL.md's feedback P <- Wc^-1 (T - A_c - ds (Ww P + eta Aw)), iterated where
    it converges, ends where our one-step per-pixel solve starts."""
    _, _, _, _, cal = world
    m = cal.pixel.runtime_model()
    image = uniform((90, 70, 80), W, H)
    target = np.einsum("hwij,hwj->hwi", m.Ww, m.fwd_lut[image, [0, 1, 2]]) + m.Aw
    for angle in (80, 100):  # small lobe changes: the iteration contracts
        eye = eye_from_angle(angle, 0.5, 0.035)
        exact = target_to_projector(m, target.astype(np.float32), eye)
        ds = lobe_change(m, eye).astype(np.float64)
        wc_inv = np.linalg.inv(m.Wc.astype(np.float64))
        p = np.einsum("hwij,hwj->hwi", wc_inv, target - m.Ac)
        for _ in range(200):
            spec = ds * (np.einsum("hwij,hwj->hwi", m.Ww, p) + m.lobe_black * m.Aw)
            p = np.einsum("hwij,hwj->hwi", wc_inv, target - m.Ac - spec)
        np.testing.assert_allclose(p, exact, atol=2e-4)


def test_bundle_round_trip_gives_the_same_output_within_one_level(world, tmp_path):
    """The bundle stores the per-pixel maps with an error bound (viewcomp.calib.io.compact)
    and the geometry not at all: the output stays within one level, the geometry exact."""
    *_, cal = world
    path = tmp_path / "screen.vcb"
    cal.save(path)
    again = Calibration.load(path)
    for name in ("pos", "refl", "projector", "camera"):
        a, b = getattr(cal.pixel.geometry, name), getattr(again.pixel.geometry, name)
        np.testing.assert_array_equal(a, b)
    for method in ("pixel", "paper"):
        for rgb, angle in (((120, 40, 200), 70), ((200, 30, 30), 100), ((20, 10, 40), 60)):
            eye = eye_from_angle(angle, 0.5, 0.035)
            image = uniform(rgb, W, H)
            a = Compensation(cal, method).compensate_image(image, eye)[0]
            b = Compensation(again, method).compensate_image(image, eye)[0]
            diff = np.abs(a.astype(int) - b)
            assert diff.max() <= 1, (method, rgb, angle)
            if method == "paper":  # global numbers, stored exactly
                assert diff.max() == 0


def test_corrupt_and_truncated_bundles_are_refused(world, tmp_path):
    *_, cal = world
    path = tmp_path / "screen.vcb"
    cal.save(path)
    data = path.read_bytes()
    (tmp_path / "half.vcb").write_bytes(data[: len(data) // 2])
    with pytest.raises(BundleError, match=r"half\.vcb"):
        Calibration.load(tmp_path / "half.vcb")
    (tmp_path / "text.vcb").write_text("not a bundle")
    with pytest.raises(BundleError):
        Calibration.load(tmp_path / "text.vcb")


def _capture_dir(tmp_path, white, real, sim):
    from viewcomp.calib.io.captureset import write_capture_set

    d = tmp_path / "caps"
    write_capture_set(d, sim.rig, white, real)
    return d


def test_saturated_capture_is_refused_by_name(world, tmp_path):
    sim, _, white, real, _ = world
    real = dict(real)
    hot = real["gray"].copy()
    hot[: H // 2] = 255
    real["gray"] = hot
    with pytest.raises(FitError, match=r"screen/gray.*saturated"):
        calibrate(read_capture_set(_capture_dir(tmp_path, white, real, sim)))


def test_mirrored_ramp_and_swapped_patterns_are_refused(world, tmp_path):
    sim, _, white, real, _ = world
    # The real screen's ramp serves the paper's method alone: without it the bundle holds
    # the per-pixel method, says why, and refuses the paper's method by name.
    mirrored = dict(real, ramp=real["ramp"][:, ::-1].copy())
    cal = calibrate(capture_set_from_raw(sim.rig, white, mirrored))
    assert cal.methods == ("pixel",) and "screen/ramp" in cal.info["paper_error"]
    with pytest.raises(BundleError, match=r"per-pixel method.*screen/ramp.*--method pixel"):
        Compensation(cal, "paper")
    path = tmp_path / "pixel-only.vcb"
    cal.save(path)
    again = Calibration.load(path)
    assert again.methods == ("pixel",) and again.paper is None
    image = uniform((120, 40, 200), W, H)
    eye = eye_from_angle(70, 0.5, 0.035)
    np.testing.assert_allclose(  # the compact maps' bound (test_bundle_round_trip_...)
        Compensation(cal, "pixel").compensate_image(image, eye)[0],
        Compensation(again, "pixel").compensate_image(image, eye)[0],
        atol=1,
    )
    # The white screen's ramp is the per-pixel method's response: mirrored, nothing fits.
    with pytest.raises(FitError, match="white/ramp"):
        calibrate(capture_set_from_raw(sim.rig, dict(white, ramp=white["ramp"][:, ::-1]), real))
    swapped = dict(real, red=real["green"], green=real["red"])
    with pytest.raises(FitError, match=r"swapped"):
        calibrate(capture_set_from_raw(sim.rig, white, swapped))


def test_dark_capture_is_refused(world):
    sim, _, white, real, _ = world
    dark = {k: (v // 40).astype(np.uint8) for k, v in real.items()}
    with pytest.raises(FitError, match="too dark"):
        calibrate(capture_set_from_raw(sim.rig, white, dark))


def test_capture_set_on_disk_is_not_modified_by_calibrate(tmp_path):
    d = tmp_path / "caps"
    simulate_capture_set(d, "red", "glossy", rig=small_simulator(W, H).rig)
    before = {p: p.read_bytes() for p in sorted(d.rglob("*")) if p.is_file()}
    calibrate(read_capture_set(d)).save(tmp_path / "b.vcb")
    after = {p: p.read_bytes() for p in sorted(d.rglob("*")) if p.is_file()}
    assert before == after


def test_without_black_capture_ambient_is_estimated(tmp_path):
    sim = small_simulator(W, H, seed=2)
    screen = make_screen("green", "glossy")
    white = capture_patterns(sim, white_screen(), black=False)
    real = capture_patterns(sim, screen, black=False)
    cal = calibrate(capture_set_from_raw(sim.rig, white, real))
    assert not cal.pixel.screen.ambient_measured
    truth = sim.true_ambient(screen, vignetting=True)
    est = cal.pixel.screen.A
    assert np.abs(est.mean(axis=(0, 1)) - truth.mean(axis=(0, 1))).max() < 0.01


def test_small_calibration_helper_is_real():
    cal = small_calibration()
    assert cal.shape == (32, 64) and cal.pixel.lobe.peak.max() > 0.2


def test_read_capture_set_names_the_missing_file(tmp_path):
    d = tmp_path / "caps"
    simulate_capture_set(d, "red", "matte", rig=small_simulator(W, H).rig)
    (d / "screen" / "ramp.png").unlink()
    with pytest.raises(Exception, match="screen/ramp"):
        read_capture_set(d)
    shutil.rmtree(d / "screen")
    img = read_image(d / "white" / "gray.png")
    write_png(d / "white" / "gray.png", img[:10])
    with pytest.raises(Exception, match="gray"):
        read_capture_set(d)
