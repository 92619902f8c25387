"""The simulated camera in its own image: geometry with lens distortion, the same physics as
the projector-grid simulator, and the camera-space capture set."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest

from viewcomp.calib.io.captureset import read_capture_set
from viewcomp.calib.io.patterns import table1_patterns
from viewcomp.calib.sim.simcamera import (
    SIM_CAMERA_DISTORTION,
    SimCamera,
    camera_rig,
    scaled_camera_rig,
    simulate_camera_set,
    true_camera_points,
    true_projector_map,
)
from viewcomp.calib.sim.simulate import simulate_capture_set
from viewcomp.calib.sim.simulator import (
    CameraPhysics,
    Simulator,
    make_screen,
    simulation_rig,
    white_screen,
)
from viewcomp.calib.world.rig import Rig, load_rig


def small_rig(w: int = 160, h: int = 80) -> Rig:
    """The simulation rig with a w x h projector, camera scaled alike, lens included."""
    rig = simulation_rig()
    rig = replace(rig, projector=replace(rig.projector, resolution=(w, h)))
    return scaled_camera_rig(rig, (w, h))


def test_camera_rig_adds_the_default_lens_and_camera_space() -> None:
    rig = camera_rig(simulation_rig())
    assert rig.camera.distortion == SIM_CAMERA_DISTORTION
    assert rig.capture.space == "camera"
    lensed = replace(simulation_rig().camera, distortion=(0.0, 0.0, 0.0, 0.0, 0.0))
    kept = camera_rig(replace(simulation_rig(), camera=lensed))
    assert kept.camera.distortion == (0.0, 0.0, 0.0, 0.0, 0.0)  # a given lens is kept


def test_view_maps_camera_pixels_back_to_the_projector_pixels_that_light_them() -> None:
    rig = small_rig()
    cam = SimCamera(Simulator(rig=rig))
    uv = np.array([[10.0, 7.0], [80.0, 40.0], [150.5, 70.25]])
    xy = true_camera_points(rig, uv)
    # the distortion moves points measurably against the pinhole
    pinhole = replace(rig, camera=replace(rig.camera, distortion=None))
    assert np.abs(true_camera_points(pinhole, uv) - xy).max() > 0.3
    for (u, v), (x, y) in zip(uv, xy, strict=True):
        # map at the (generally non-integer) camera point, bilinearly
        mu = cv2.getRectSubPix(cam.view.map_u, (1, 1), (float(x), float(y)))[0, 0]
        mv = cv2.getRectSubPix(cam.view.map_v, (1, 1), (float(x), float(y)))[0, 0]
        assert abs(mu - u) < 0.02 and abs(mv - v) < 0.02
    assert cam.view.inside.any() and not cam.view.inside.all()  # the surround is seen


def test_camera_image_is_the_projector_grid_physics_resampled() -> None:
    """Noise-free camera signal at the camera point of projector pixel x equals the
    projector-grid simulator's signal at x (radiance, exposure, vignetting)."""
    rig = small_rig()
    sim = Simulator(rig=rig)
    cam = SimCamera(sim, blur_px=0.0)
    screen = make_screen("magenta", "glossy")
    w, h = rig.projector.resolution
    img = table1_patterns(w, h)["ramp"]
    lin = cam.linear(screen, img)
    grid = sim.expose(sim.radiance(screen, img, sim.geometry.camera), vignetting=True)
    cam_xy = true_projector_map(rig)
    rng = np.random.default_rng(0)
    for _ in range(40):
        u, v = int(rng.integers(3, w - 3)), int(rng.integers(3, h - 3))
        x, y = cam_xy[v, u]
        got = np.array(
            [cv2.getRectSubPix(lin[..., c], (1, 1), (float(x), float(y)))[0, 0] for c in range(3)]
        )
        # two bilinear resamplings of a smooth ramp under a smooth lobe
        np.testing.assert_allclose(got, grid[v, u], rtol=0.01, atol=1e-3)


def test_surround_is_lit_by_the_room_only() -> None:
    rig = small_rig()
    sim = Simulator(rig=rig)
    cam = SimCamera(sim, blur_px=0.0)
    w, h = rig.projector.resolution
    lit = cam.linear(white_screen(), np.full((h, w, 3), 255, np.uint8))
    dark = cam.linear(white_screen(), np.zeros((h, w, 3), np.uint8))
    outside = ~cam.view.inside
    np.testing.assert_allclose(lit[outside], dark[outside], atol=1e-6)
    amb = 0.85 * np.asarray(sim.ambient) * sim.camera.exposure
    assert np.all(lit[outside] <= amb * 1.0001)
    assert lit[cam.view.inside].mean() > 20 * lit[outside].mean()


def test_capture_is_8_bit_noisy_and_seeded() -> None:
    rig = small_rig()
    cam = SimCamera(Simulator(rig=rig, seed=2))
    w, h = rig.projector.resolution
    gray = table1_patterns(w, h)["gray"]
    screen = make_screen("red", "glossy")
    a = cam.capture(screen, gray, "k")
    b = cam.capture(screen, gray, "k")
    c = cam.capture(screen, gray, "other")
    cw, ch = rig.camera.resolution
    assert a.shape == (ch, cw, 3) and a.dtype == np.uint8
    assert np.array_equal(a, b) and not np.array_equal(a, c)


def test_full_size_render() -> None:
    """A capture at the camera's full 1280x720 (its time: bench/bench_simcamera.py; tests
    hold no timed assertions)."""
    rig = camera_rig(simulation_rig())
    cam = SimCamera(Simulator(rig=rig))
    w, h = rig.projector.resolution
    out = cam.capture(make_screen("magenta", "glossy"), table1_patterns(w, h)["gray"], "k")
    assert out.shape == (720, 1280, 3) and out.dtype == np.uint8
    assert 0 < out.mean() < 255


def test_simulate_camera_set_writes_a_camera_space_set(tmp_path) -> None:
    rig = replace(
        simulation_rig(), projector=replace(simulation_rig().projector, resolution=(160, 80))
    )
    rig = replace(rig, camera=replace(rig.camera, resolution=(320, 180)))
    paths = simulate_camera_set(tmp_path / "cs", "green", "satin", seed=1, rig=rig)
    names = {p.relative_to(tmp_path / "cs").as_posix() for p in paths}
    assert {"rig.toml", "white/chessboard.png", "screen/chessboard.png"} <= names
    assert {"screen/graycode_white.png", "screen/graycode_black.png"} <= names
    assert "screen/graycode_00.png" in names and "white/graycode_00.png" not in names
    written = load_rig(tmp_path / "cs" / "rig.toml")
    assert written.capture.space == "camera"
    assert written.camera.distortion is None  # the lens is for calibrate to find
    cs = read_capture_set(tmp_path / "cs")
    assert cs.size == (320, 180)
    assert {p.stem for p in cs.extra["screen"]} >= {"chessboard", "graycode_00"}


def test_simulate_capture_set_dispatches_camera_space(tmp_path) -> None:
    rig = replace(
        simulation_rig(), projector=replace(simulation_rig().projector, resolution=(96, 48))
    )
    rig = replace(rig, camera=replace(rig.camera, resolution=(192, 108)))
    simulate_capture_set(tmp_path / "cs", space="camera", rig=rig, black=False)
    cs = read_capture_set(tmp_path / "cs")
    assert cs.rig.capture.space == "camera" and not cs.has_black


def test_bad_blur_is_refused() -> None:
    with pytest.raises(ValueError, match="blur_px"):
        SimCamera(Simulator(rig=small_rig()), blur_px=-1.0)


def test_more_frames_means_less_noise() -> None:
    rig = small_rig()
    w, h = rig.projector.resolution
    gray = table1_patterns(w, h)["gray"]
    spread = []
    for frames in (1, 16):
        sim = Simulator(rig=rig, camera=CameraPhysics(frames=frames, bits=16))
        cam = SimCamera(sim)
        a = cam.capture(white_screen(), gray, "a").astype(np.float64)
        b = cam.capture(white_screen(), gray, "b").astype(np.float64)
        spread.append(float(np.std(a - b)))
    assert spread[1] < 0.5 * spread[0]
