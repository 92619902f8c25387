"""Phase shifting with a Gray code the camera only partly resolves: the patterns, the phase
through a non-linear projector, and a camera coarser than the projector (0.6 camera px per
projector px, integrating over its pixels) decoded against the simulator's truth."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from viewcomp.calib.errors import FitError
from viewcomp.calib.geo.captures import Captures
from viewcomp.calib.geo.graycode import decode_graycode, resolved_planes
from viewcomp.calib.geo.phaseshift import coarse_position, decode_phase, has_phase, wrapped_phase
from viewcomp.calib.geo.rectify import calibrate_geometry
from viewcomp.calib.hw.plan import capture_plan
from viewcomp.calib.io.captureset import capture_set_from_raw
from viewcomp.calib.io.patterns import graycode_patterns, phase_names, phase_patterns
from viewcomp.calib.sim.simcamera import (
    SimCamera,
    capture_camera_patterns,
    geometric_patterns,
    scaled_camera_rig,
    true_camera_points,
    true_projector_map,
    written_rig,
)
from viewcomp.calib.sim.simulator import Simulator, make_screen, simulation_rig
from viewcomp.calib.world.rig import Rig

SIZE = (320, 160)  # projector


def coarse_rig(camera_per_projector: float = 0.6) -> Rig:
    """The simulation rig with a SIZE projector and a camera of ``camera_per_projector``
    camera pixels per projector pixel (scaled_camera_rig gives 1.2)."""
    rig = simulation_rig()
    rig = replace(rig, projector=replace(rig.projector, resolution=SIZE))
    rig = scaled_camera_rig(rig, SIZE)
    f = camera_per_projector / 1.2
    cw, ch = rig.camera.resolution
    return replace(rig, camera=replace(rig.camera, resolution=(round(cw * f), round(ch * f))))


def test_phase_patterns_are_the_shifted_cosines() -> None:
    pats = phase_patterns(64, 32, period=16, shifts=4)
    assert list(pats) == ["phase_col_0", "phase_col_1", "phase_col_2", "phase_col_3"] + [
        f"phase_row_{n}" for n in range(4)
    ]
    col0, col1 = pats["phase_col_0"][0, :, 0], pats["phase_col_1"][0, :, 0]
    # 192 + 63 (1 + cos(2 pi u / 16)) / 2: 255 at u = 0 and 16, 223.5 at u = 4, 192 at u = 8
    assert (col0[0], col0[4], col0[8], col0[16]) == (255, 224, 192, 255)
    # a quarter-period shift: the peak moves to u = 4
    assert col1[4] == 255 and col1[12] == 192
    assert np.all(pats["phase_col_2"] == pats["phase_col_2"][:1])  # constant down the columns
    row3 = pats["phase_row_3"][:, 0, 0]
    assert row3[12] == 255 and row3[4] == 192
    with pytest.raises(ValueError, match="at least 3"):
        phase_patterns(64, 32, shifts=2)


def test_phase_patterns_join_the_geometric_patterns_and_the_capture_plan() -> None:
    geo = geometric_patterns(64, 32)
    assert set(phase_names()) <= set(geo)
    # the captures written (gray shown again between them is only checked)
    names = [s.name for s in capture_plan(64, 32) if s.sub == "screen" and not s.check_only]
    assert names[-len(phase_names()) :] == phase_names()


@pytest.mark.parametrize(("shifts", "limit"), [(3, None), (4, None), (8, 0.02)])
def test_enough_shifts_cancel_the_projector_response(shifts: int, limit: float | None) -> None:
    """A gamma-2.4 projector turns the sinusoid into harmonics; with 8 shifts they cancel in
    the phase, with 3 or 4 one aliases onto the fundamental."""
    period = 32
    u = np.linspace(0.0, 2 * period, 641)[None, :]  # sub-pixel positions, two periods
    imgs = []
    for n in range(shifts):
        level = np.floor(255 * (0.5 + 0.5 * np.cos(2 * np.pi * (u / period - n / shifts))) + 0.5)
        imgs.append(0.004 + 0.996 * (level / 255.0) ** 2.4)  # light, not level
    phase, amp = wrapped_phase(imgs)
    got = phase * period / (2 * np.pi)
    err = (got - u + period / 2) % period - period / 2
    rms = float(np.sqrt(np.mean(err**2)))
    if limit is None:
        assert rms > 0.05  # what too few shifts cost
    else:
        assert rms < limit
    assert amp.min() > 0.3


def test_coarse_position_decodes_kept_planes_to_intervals() -> None:
    planes, _, _ = graycode_patterns(64, 32)
    table = np.stack([planes[2 * k][0, :, 0] > 0 for k in range(6)])  # column planes
    u = np.array([0, 5, 17, 40, 63])
    # the three coarsest planes: intervals of 8 columns
    bits = table[:3][:, u].reshape(3, 1, len(u))
    centre, half = coarse_position(bits, table[:3])
    np.testing.assert_array_equal(centre[0], [3.5, 3.5, 19.5, 43.5, 59.5])
    np.testing.assert_array_equal(half[0], 3.5)


def test_resolved_planes_drop_every_finer_plane_after_a_failure() -> None:
    contrast = np.array([1.0, 0.9, 0.2, 0.6, 1.0, 0.1])
    widths = np.array([32, 16, 4, 8, 16, 4])
    got = resolved_planes(contrast, widths, n_col=4)
    # columns: the 4-px plane fails, the 8-px one passes; rows: the 4-px one fails
    np.testing.assert_array_equal(got, [True, True, False, True, True, False])
    contrast = np.array([1.0, 0.2, 0.9, 0.9])
    widths = np.array([32, 16, 8, 4])
    np.testing.assert_array_equal(resolved_planes(contrast, widths, 4), [1, 0, 0, 0])


class CoarseWorld:
    """An area-integrating camera at 0.6 camera px per projector px (blur, noise, lens) sees
    the Gray code and the phase shifts on a glossy magenta screen."""

    def __init__(self) -> None:
        self.rig = coarse_rig(0.6)
        sim = Simulator(rig=self.rig, seed=3)
        self.cam = SimCamera(sim, supersample=4)
        screen = make_screen("magenta", "glossy", shape=sim.shape)
        self.real = capture_camera_patterns(self.cam, screen, black=False)

    def captures(self, real: dict[str, np.ndarray] | None = None) -> Captures:
        table1 = {k: v for k, v in self.real.items() if not k.startswith(("graycode", "phase"))}
        cs = capture_set_from_raw(written_rig(self.rig), table1, real or self.real)
        return Captures(cs, "screen")


@pytest.fixture(scope="module")
def coarse() -> CoarseWorld:
    return CoarseWorld()


def _at_projector_pixels(world: CoarseWorld, position: np.ndarray, ok: np.ndarray):
    """For every projector pixel (the camera sees them all): whether the camera pixel nearest
    to where the camera sees it decoded, and that camera pixel's decoded and true projector
    positions (the truth: where the pixel centre's ray meets the screen, in projector px)."""
    w, h = SIZE
    uu, vv = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    xy = true_camera_points(world.rig, np.stack([uu, vv], -1))
    cw, ch = world.rig.camera.resolution
    xi, yi = np.rint(xy[..., 0]).astype(int), np.rint(xy[..., 1]).astype(int)
    assert ((xi >= 0) & (xi < cw) & (yi >= 0) & (yi < ch)).all()  # all in view
    mapped = ok[yi, xi]
    view = world.cam.view
    truth = np.stack([view.map_u[yi, xi], view.map_v[yi, xi]], -1)[mapped]
    return mapped, position[yi, xi][mapped], truth


@pytest.mark.slow
def test_a_coarse_camera_maps_the_projector_to_sub_pixels(coarse: CoarseWorld) -> None:
    caps = coarse.captures()
    assert has_phase(caps)
    gc = decode_graycode(caps, SIZE)
    # the finest planes (2-px stripes: 1.2 camera px) come out unresolved, the rest kept
    widths = gc.stripe_widths()
    assert not gc.resolved()[widths == 2].any() and gc.resolved()[widths >= 8].all()
    pm = decode_phase(caps, gc)
    mapped, got, truth = _at_projector_pixels(coarse, pm.position, pm.ok)
    assert mapped.mean() >= 0.95, f"{mapped.mean():.1%} of the projector pixels mapped"
    err = np.linalg.norm(got - truth, axis=-1)
    rms = float(np.sqrt(np.mean(err**2)))
    assert rms < 0.3, f"{rms:.3f} projector px RMS"
    # the Gray code alone (every bit reliable) maps a minority of them, whole pixels only
    old, _, _ = _at_projector_pixels(coarse, gc.positions(), gc.column >= 0)
    assert old.mean() < 0.6


@pytest.mark.slow
def test_a_coarse_camera_calibrates_the_geometry(coarse: CoarseWorld) -> None:
    cs = coarse.captures().cs
    geo = calibrate_geometry(cs)
    assert geo.stats["phase"]["graycode_planes_dropped"] == 2  # the 2-px stripes
    err = np.linalg.norm(np.stack(geo.map.grid(), -1) - true_projector_map(coarse.rig), axis=-1)
    rms = float(np.sqrt(np.mean(err**2)))  # camera px; 0.6 camera px per projector px
    assert rms / 0.6 < 0.05, f"map {rms / 0.6:.3f} projector px RMS from the truth"
    # the Gray code alone, every bit reliable, does not decode enough of the frame
    real = {k: v for k, v in coarse.real.items() if not k.startswith("phase_")}
    with pytest.raises(FitError, match=r"only \d+% of the lit camera pixels decode"):
        calibrate_geometry(coarse.captures(real).cs)


def test_a_partial_set_of_phase_captures_is_refused(coarse: CoarseWorld) -> None:
    real = {k: v for k, v in coarse.real.items() if k != "phase_row_5"}
    with pytest.raises(FitError, match=r"screen/phase_row_5.*not found.*phase_col_0"):
        has_phase(coarse.captures(real))
    none = {k: v for k, v in coarse.real.items() if not k.startswith("phase_")}
    assert not has_phase(coarse.captures(none))


def test_a_camera_too_coarse_for_the_period_is_refused(coarse: CoarseWorld) -> None:
    caps = coarse.captures()
    gc = decode_graycode(caps, SIZE)
    # at 0.6 camera px the 8-px stripes resolve; a 16-px period needs 4-px ones resolved,
    # an 8-px period 2-px ones, which do not
    with pytest.raises(FitError, match=r"graycode_\d+.*2-px stripes.*move the camera closer"):
        decode_phase(caps, gc, period=8)


def test_the_default_camera_samples_points_and_supersampling_integrates_pixels() -> None:
    rig = coarse_rig(0.6)
    sim = Simulator(rig=rig, seed=0)
    w, h = SIZE
    # one-pixel vertical stripes, far finer than the camera's 1.67 projector px per pixel
    stripes = np.zeros((h, w, 3), np.uint8)
    stripes[:, ::2] = 255
    white = make_screen("white", "matte", shape=sim.shape)
    point = SimCamera(sim, blur_px=0.0)
    area = SimCamera(sim, blur_px=0.0, supersample=5)
    # supersample=1 is the default camera, number for number
    np.testing.assert_array_equal(
        SimCamera(sim, supersample=1).linear(white, stripes), SimCamera(sim).linear(white, stripes)
    )
    full = point.linear(white, np.full((h, w, 3), 255, np.uint8))
    inner = point.view.inside.copy()
    inner[:, :3] = inner[:, -3:] = inner[:3] = inner[-3:] = False
    for cam in (point, area):
        assert cam.linear(white, stripes).shape == (*cam.shape, 3)
    rel_point = point.linear(white, stripes)[inner] / full[inner]
    rel_area = area.linear(white, stripes)[inner] / full[inner]
    # a point sample lands anywhere between a lit and a dark projector pixel: 0..1 of white;
    # a pixel's area (1.67 projector px wide) holds about half light, half dark
    assert rel_point.std() > 0.2
    assert abs(float(np.median(rel_area)) - 0.5) < 0.05 and rel_area.std() < 0.12
    with pytest.raises(ValueError, match="supersample"):
        SimCamera(sim, supersample=0)


def test_simulated_camera_sets_hold_the_phase_captures(tmp_path) -> None:
    from viewcomp.calib.io.captureset import read_capture_set
    from viewcomp.calib.sim.simulate import simulate_capture_set

    rig = simulation_rig()
    rig = replace(rig, projector=replace(rig.projector, resolution=(160, 80)))
    simulate_capture_set(tmp_path / "caps", space="camera", rig=scaled_camera_rig(rig, (160, 80)))
    cs = read_capture_set(tmp_path / "caps")
    assert {p.stem for p in cs.extra["screen"]} >= set(phase_names())
    assert not {p.stem for p in cs.extra["white"]} & set(phase_names())
