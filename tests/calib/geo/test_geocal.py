"""Geometric calibration of camera-space captures: the map against the simulator's truth,
rectification, and the refusals (chessboard, order, saturation, camera moved)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest

from viewcomp.calib.errors import FitError
from viewcomp.calib.eval.evaluate import World as EvalWorld
from viewcomp.calib.eval.evaluate import check_table2, sweep, sweep_means, table2
from viewcomp.calib.eval.testimages import natural_images
from viewcomp.calib.fit.calibrate import calibrate
from viewcomp.calib.fit.colourguide import GUIDE_RADIUS_PX
from viewcomp.calib.geo.camresponse import estimate_response, estimate_set_response
from viewcomp.calib.geo.projmap import rectify
from viewcomp.calib.geo.rectify import BORDER_PX, calibrate_geometry, rectify_capture_set
from viewcomp.calib.io.captureset import capture_set_from_raw, write_capture_set
from viewcomp.calib.io.imageio import to_linear
from viewcomp.calib.io.patterns import chessboard
from viewcomp.calib.sim.simcamera import (
    SimCamera,
    capture_camera_patterns,
    scaled_camera_rig,
    true_projector_map,
    written_rig,
)
from viewcomp.calib.sim.simulate import capture_patterns
from viewcomp.calib.sim.simulator import (
    CameraPhysics,
    Simulator,
    make_screen,
    simulation_rig,
    white_screen,
)
from viewcomp.calib.world.lens import distort_normalised
from viewcomp.calib.world.rig import Rig
from viewcomp.cli import main

SIZE = (320, 160)  # projector; the camera is 640x360, ~1.2 camera px per projector px


def _rig(size: tuple[int, int] = SIZE) -> Rig:
    rig = simulation_rig()
    rig = replace(rig, projector=replace(rig.projector, resolution=size))
    return scaled_camera_rig(rig, size)


class World:
    """A small simulated rig with its camera-space captures, made once per module."""

    def __init__(self) -> None:
        self.rig = _rig()
        self.sim = Simulator(rig=self.rig, seed=1)
        self.cam = SimCamera(self.sim)
        self.screen = make_screen("magenta", "glossy", shape=self.sim.shape)
        self.white = capture_camera_patterns(self.cam, white_screen(), geometric="chessboard")
        self.real = capture_camera_patterns(self.cam, self.screen)

    def cs(
        self,
        white: dict[str, np.ndarray] | None = None,
        real: dict[str, np.ndarray] | None = None,
    ):
        return capture_set_from_raw(written_rig(self.rig), white or self.white, real or self.real)

    def moved_camera(self, dx: float) -> SimCamera:
        c = self.rig.camera
        pos = (c.position[0] + dx, *c.position[1:])
        look = (c.look_at[0] + dx, *c.look_at[1:])
        rig = replace(self.rig, camera=replace(c, position=pos, look_at=look))
        return SimCamera(Simulator(rig=rig, seed=1))


@pytest.fixture(scope="module")
def world() -> World:
    return World()


@pytest.fixture(scope="module")
def geometry(world: World):
    return calibrate_geometry(world.cs())


def test_lens_model_matches_opencv() -> None:
    # cv2.projectPoints of normalised points with K = I is OpenCV's distortion itself
    rng = np.random.default_rng(0)
    pts = rng.uniform(-0.4, 0.4, (50, 2))
    dist = np.array([-0.08, 0.02, 0.001, -0.002, 0.003])
    ref, _ = cv2.projectPoints(
        np.c_[pts, np.ones(50)].reshape(-1, 1, 3), np.zeros(3), np.zeros(3), np.eye(3), dist
    )
    got = np.stack(distort_normalised(pts[:, 0], pts[:, 1], dist), -1)
    np.testing.assert_allclose(got, ref.reshape(-1, 2), atol=1e-12)


def test_map_recovers_the_true_projector_to_camera_map(world: World, geometry) -> None:
    truth = true_projector_map(world.rig)
    est = np.stack(geometry.map.grid(), -1)
    err = np.linalg.norm(est - truth, axis=-1)
    rms = float(np.sqrt(np.mean(err**2)))
    assert rms < 0.5, f"map RMS {rms:.3f} camera px"
    assert rms < 0.1  # measured ~0.02: a regression guard well inside the requirement
    # the lens was not given to calibrate (written_rig leaves it out), yet it is found
    k1, k2 = geometry.map.distortion[:2]
    assert abs(k1 - (-0.08)) < 0.02 and abs(k2 - 0.02) < 0.05


def test_chessboard_and_reprojection_errors_are_reported(geometry) -> None:
    st = geometry.stats
    assert st["chessboard"]["corners"] == 40
    assert st["chessboard"]["zhang_rms_px"] < 0.2
    assert st["chessboard"]["white_vs_screen_px"] < 0.2
    assert st["map"]["chessboard_rms_px"] < 0.2
    assert 0.2 < st["graycode"]["rms_px"] < 0.7  # Gray code quantises to whole projector px
    # the camera resolves every plane: the phase is decoded, the map keeps the Gray code
    assert st["phase"]["decoded_fraction_of_lit"] > 0.95
    assert st["phase"]["used_for_map"] is False
    assert st["graycode"]["plane_agreement_min"] > 0.95
    assert st["max_frame_shift_px"] < 0.3


def test_a_set_without_phase_captures_calibrates_with_the_gray_code_alone(world) -> None:
    real = {k: v for k, v in world.real.items() if not k.startswith("phase_")}
    geo = calibrate_geometry(world.cs(real=real))
    assert "phase" not in geo.stats and geo.graycode.subpixel is None
    assert 0.2 < geo.stats["graycode"]["rms_px"] < 0.7  # whole projector pixels
    truth = true_projector_map(world.rig)
    err = np.linalg.norm(np.stack(geo.map.grid(), -1) - truth, axis=-1)
    assert float(np.sqrt(np.mean(err**2))) < 0.1


def test_rectified_chessboard_corners_land_on_the_projector_corners(world, geometry) -> None:
    lin = to_linear(world.real["chessboard"], world.rig.camera.response)
    rect = rectify(lin, geometry.map.grid())
    g = rect.mean(axis=2)
    g8 = np.clip(g / np.percentile(g, 99.9) * 255, 0, 255).astype(np.uint8)
    ok, found = cv2.findChessboardCorners(g8, (8, 5))
    assert ok
    found = cv2.cornerSubPix(
        g8, found, (5, 5), (-1, -1), (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 1e-3)
    ).reshape(-1, 2)
    _, truth = chessboard(*SIZE)
    if np.linalg.norm(found[0] - truth[0]) > np.linalg.norm(found[-1] - truth[0]):
        found = found[::-1]
    rms = float(np.sqrt(np.mean(np.sum((found - truth) ** 2, axis=1))))
    assert rms < 0.5, f"rectified corners {rms:.3f} projector px from the truth"


def test_graycode_decodes_the_true_projector_pixels(world, geometry) -> None:
    gc = geometry.graycode
    ok = gc.column >= 0
    assert ok.sum() > 0.5 * world.cam.view.inside.sum()
    true_u = world.cam.view.map_u[ok]
    true_v = world.cam.view.map_v[ok]
    du = gc.column[ok] - true_u
    dv = gc.row[ok] - true_v
    assert np.mean(np.abs(du) <= 1.0) > 0.995 and np.mean(np.abs(dv) <= 1.0) > 0.995
    # decoded codes are the nearest projector pixel: unbiased, ~uniform in +-0.5
    assert abs(du.mean()) < 0.05 and abs(dv.mean()) < 0.05
    assert np.sqrt(np.mean(du**2)) < 0.45 and np.sqrt(np.mean(dv**2)) < 0.45


def test_rectified_captures_match_the_projector_space_captures(world) -> None:
    rect, stats = rectify_capture_set(world.cs())
    truth_sim = Simulator(rig=world.rig, seed=1)
    truth = capture_patterns(truth_sim, world.screen)
    w, h = SIZE
    assert rect.size == (w, h)
    inner = (slice(2, -2), slice(2, -2))
    for name in ("gray", "red", "ramp", "black"):
        ref = to_linear(truth[name], world.rig.camera.response)
        got = rect.screen[name]
        assert got.shape == (h, w, 3) and got.dtype == np.float32
        rel = abs(float(got[inner].mean() / ref[inner].mean()) - 1.0)
        assert rel < 0.01, f"{name}: mean differs by {rel:.2%}"
        if name != "black":  # the border ring copies its neighbours, within a few percent
            edge = float(got[0].mean() / ref[0].mean())
            assert 0.95 < edge < 1.05
    assert stats["seconds"] > 0 and BORDER_PX == 1
    # the simulator's camera (1.2 camera px per projector px) blurs the edge over a line or two
    assert all(1 <= v <= 2 for v in stats["edge_zone_px"].values()), stats["edge_zone_px"]


def test_calibrate_accepts_camera_space_and_reports_geometry(world) -> None:
    cal = calibrate(world.cs())
    geo = cal.info["geometry"]
    assert geo["space"] == "camera" and geo["chessboard"]["zhang_rms_px"] < 0.2
    assert cal.shape == (SIZE[1], SIZE[0])
    # a real camera's set: its colour mixing smoothed where the screen's colour is uniform
    assert cal.info["colour_guide_px"] == GUIDE_RADIUS_PX > 0


# -- refusals ------------------------------------------------------------------------------


def test_refuses_a_missing_chessboard(world) -> None:
    real = dict(world.real)
    real["chessboard"] = world.real["gray"]
    with pytest.raises(FitError, match=r"screen/chessboard.*no chessboard"):
        calibrate(world.cs(real=real))


def test_refuses_graycode_planes_out_of_order(world) -> None:
    real = dict(world.real)
    real["graycode_04"], real["graycode_06"] = world.real["graycode_06"], world.real["graycode_04"]
    with pytest.raises(FitError, match=r"graycode_0[46].*out of order"):
        calibrate(world.cs(real=real))


def test_refuses_a_plane_swapped_with_its_inverse(world) -> None:
    real = dict(world.real)
    real["graycode_02"], real["graycode_03"] = world.real["graycode_03"], world.real["graycode_02"]
    with pytest.raises(FitError, match=r"graycode_02.*look swapped"):
        calibrate(world.cs(real=real))


def test_refuses_table1_captures_in_the_wrong_order(world) -> None:
    real = dict(world.real)
    real["red"], real["green"] = world.real["green"], world.real["red"]
    with pytest.raises(FitError, match=r"screen/red.*wrong order"):
        calibrate(world.cs(real=real))


def test_refuses_a_mirrored_ramp(world) -> None:
    white = dict(world.white)
    # the ramp's pattern mirrored: what a projector set to rear projection shows
    w, h = SIZE
    pat = capture_camera_patterns.__globals__["table1_patterns"](w, h)["ramp"][:, ::-1]
    white["ramp"] = world.cam.capture(white_screen(), np.ascontiguousarray(pat), "mirror")
    with pytest.raises(FitError, match=r"white/ramp.*left to right"):
        calibrate(world.cs(white=white))


def test_refuses_saturated_captures(world) -> None:
    hot = Simulator(rig=world.rig, seed=1, camera=CameraPhysics(exposure=2.5))
    cam = SimCamera(hot)
    real = dict(world.real)
    real.update(capture_camera_patterns(cam, world.screen, geometric="none"))
    with pytest.raises(FitError, match="saturated"):
        calibrate(world.cs(real=real))


def test_refuses_a_camera_moved_during_the_graycode(world) -> None:
    moved = world.moved_camera(0.003)  # 3 mm: ~3 camera px
    real = dict(world.real)
    later = capture_camera_patterns(moved, world.screen, black=False)
    real.update({k: v for k, v in later.items() if k.startswith("graycode_")})
    with pytest.raises(FitError, match="camera moved"):
        calibrate(world.cs(real=real))


def test_refuses_a_camera_moved_between_the_two_screens(world) -> None:
    moved = world.moved_camera(0.002)
    white = capture_camera_patterns(moved, white_screen(), geometric="chessboard")
    with pytest.raises(FitError, match=r"white/chessboard.*moved between"):
        calibrate(world.cs(white=white))


def test_refuses_a_camera_moved_before_one_capture(world) -> None:
    moved = world.moved_camera(0.002)
    real = dict(world.real)
    real["ramp"] = capture_camera_patterns(moved, world.screen, geometric="none")["ramp"]
    with pytest.raises(FitError, match=r"screen/ramp.*camera moved"):
        calibrate(world.cs(real=real))


def test_refused_set_writes_no_bundle(world, tmp_path: Path, capsys) -> None:
    real = dict(world.real)
    real["chessboard"] = world.real["black"]
    write_capture_set(tmp_path / "cs", written_rig(world.rig), world.white, real)
    out = tmp_path / "cal.vcb"
    assert main(["calibrate", str(tmp_path / "cs"), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "screen/chessboard.png" in err and "no chessboard" in err
    assert not out.exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".cal.vcb")]


def test_refuses_missing_graycode(world) -> None:
    real = {k: v for k, v in world.real.items() if k != "graycode_07"}
    with pytest.raises(FitError, match=r"screen/graycode_07.*not found"):
        calibrate(world.cs(real=real))


def test_response_is_estimated_from_the_graycode_and_a_wrong_one_refused() -> None:
    base = _rig((160, 80))
    rig = replace(base, camera=replace(base.camera, response=1.8))
    cam = SimCamera(Simulator(rig=rig, seed=2))
    screen = make_screen("blue", "glossy")
    white = capture_camera_patterns(cam, white_screen(), geometric="chessboard")
    real = capture_camera_patterns(cam, screen)
    found, misfit = estimate_set_response(capture_set_from_raw(written_rig(rig), white, real))
    assert found.kind == "gamma" and abs(found.gamma - 1.8) < 0.1 and misfit < 0.03
    stats = calibrate_geometry(capture_set_from_raw(written_rig(rig), white, real)).stats
    assert stats["response"]["rig"] == 1.8 and stats["response"]["rig_misfit"] < 0.03
    wrong = replace(written_rig(rig), camera=replace(rig.camera, response="srgb"))
    with pytest.raises(FitError, match=r"rig.toml: \[camera\] response = 'srgb' does not"):
        calibrate_geometry(capture_set_from_raw(wrong, white, real))


@pytest.mark.parametrize("truth", ["linear", "srgb", 2.4])
def test_estimate_response_on_synthetic_stripe_edges(truth) -> None:
    from viewcomp.calib.world.response import parse_response

    rng = np.random.default_rng(0)
    white = rng.uniform(0.3, 0.9, (2000, 1, 3))
    black = rng.uniform(0.0, 0.02, (2000, 1, 3))
    a = rng.uniform(0.1, 0.9, (2000, 1, 1))  # the share of the lit side on each pixel
    lin = np.concatenate(
        [a * white + (1 - a) * black, (1 - a) * white + a * black, white, black], axis=1
    )
    resp = parse_response(truth)
    codes = np.rint(resp.encode(lin) * 255) / 255
    found, misfit = estimate_response(codes)
    assert misfit < 0.01
    if truth == 2.4:
        assert found.kind == "gamma" and abs(found.gamma - 2.4) < 0.05
    else:
        assert found.spec == truth


# -- evaluation parity ---------------------------------------------------------------------


def _column_means(rows: list[dict], metric: str) -> dict[str, float]:
    return {k: float(np.mean([r[metric][k] for r in rows])) for k in rows[0][metric]}


@pytest.mark.slow
def test_evaluation_from_camera_space_matches_projector_space() -> None:
    """table2 and a reduced sweep, at 320x160, from camera-space captures (rectified by
    calibrate) against projector-space captures: every column's mean SSE and dE within 10%,
    and the paper's qualitative results the same.

    The camera-space simulator averages CAMERA_FRAMES = 2 frames against the projector-space
    capture's 4: rectification interpolates ~1.4 camera pixels per projector pixel, which
    halves the noise variance, so the noise per projector pixel is the same. (With 4 frames the
    camera path is up to 11% *better* for the per-pixel method: mean dE 2.11 vs 2.37.) Both
    calibrated with the camera-space default's colour guide, so the two differ only in the
    capture and its rectification (with it on the camera's alone, the camera path's
    per-pixel SSE is 14 % lower).
    """
    size = (320, 160)
    proj = replace(EvalWorld.make(size=size), guide_px=GUIDE_RADIUS_PX)
    cam = replace(EvalWorld.make(size=size, space="camera"), guide_px=GUIDE_RADIUS_PX)
    rows_p, rows_c = table2(proj), table2(cam)
    for metric in ("sse", "de"):
        mp, mc = _column_means(rows_p, metric), _column_means(rows_c, metric)
        for k in mp:
            assert abs(mc[k] / mp[k] - 1.0) < 0.10, (metric, k, mp[k], mc[k])
    cp, cc = check_table2(rows_p), check_table2(rows_c)
    for k in (
        "seen60_paper_theta_lt_paper_90",
        "seen90_paper_90_le_paper_theta",
        "seen90_paper_90_le_paper_60",
        "original_worst",
    ):
        assert cp[k] == cc[k], (k, cp[k], cc[k])
    for k in cp:
        assert abs(cp[k] - cc[k]) <= 1, (k, cp[k], cc[k])
    imgs = dict(list(natural_images(*size).items())[:1])
    kw = {"screens": ("red", "magenta"), "angles": (45, 90, 135), "images": imgs}
    sp, sc = sweep_means(sweep(proj, **kw)), sweep_means(sweep(cam, **kw))
    for a in sp:
        for k in sp[a]:
            assert abs(sc[a][k] / sp[a][k] - 1.0) < 0.10, (a, k, sp[a][k], sc[a][k])


def test_refuses_a_camera_that_does_not_see_the_whole_projector_image() -> None:
    base = _rig((160, 80))
    rig = replace(base, camera=replace(base.camera, fov_y=14.0))  # zoomed in: sides cut off
    cam = SimCamera(Simulator(rig=rig, seed=2))
    screen = make_screen("magenta", "glossy")
    white = capture_camera_patterns(cam, white_screen(), geometric="chessboard")
    real = capture_camera_patterns(cam, screen)
    with pytest.raises(FitError, match=r"screen/graycode_\w+: .*(not decoded|outside)"):
        calibrate_geometry(capture_set_from_raw(written_rig(rig), white, real))
