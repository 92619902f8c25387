"""The hardware emulator (viewcomp.calib.emu): frames of each camera profile, the projector's
latency and DLP sequence, rolling shutter, the webcam's automatic modes and MJPEG, noise, and
every injected fault. Expectations are derived here from the devices' documented behaviour,
not with the emulator's own functions."""

from __future__ import annotations

import math
from dataclasses import replace

import cv2
import numpy as np
import pytest

from viewcomp.calib.emu.emulator import Emulator, open_emulator
from viewcomp.calib.emu.faults import Faults, FaultSpecError, parse_bump, parse_faults
from viewcomp.calib.emu.profiles import MONO12, PROFILES, WEBCAM
from viewcomp.calib.hw.interface import FrameError

SIZE = (160, 80)
P = 1.0 / 60.0  # the projector's refresh period
W, H = SIZE
WHITE = np.full((H, W, 3), 255, np.uint8)
BLACK = np.zeros((H, W, 3), np.uint8)
GREY = np.full((H, W, 3), 128, np.uint8)


def _manual(emu: Emulator) -> None:
    """Switch a webcam's automatic modes off."""
    ctl = emu.camera.controls()
    for name in ("auto_exposure", "auto_white_balance"):
        if name in ctl:
            emu.camera.set(name, 0)


def _next_period(emu: Emulator, k: int = 1) -> float:
    """Advance the clock to the start of a refresh period ``k`` periods on; returns it."""
    t = (math.floor(emu.clock.now() / P + 1e-6) + k) * P
    emu.clock.advance_to(t)
    return t


def _show_and_wait(emu: Emulator, image: np.ndarray, periods: int = 8) -> float:
    t = emu.projector.show(image)
    emu.clock.sleep(periods * P)
    return t


@pytest.mark.parametrize(
    ("profile", "shape", "dtype", "bits", "linear"),
    [
        ("webcam", (90, 160, 3), np.uint8, 8, False),
        ("dslr", (360, 640, 3), np.uint16, 14, True),
        ("mono12", (180, 320), np.uint16, 12, True),
    ],
)
def test_profile_frames(
    profile: str, shape: tuple[int, ...], dtype: type, bits: int, linear: bool
) -> None:
    emu = open_emulator(profile, "white", seed=2, projector_size=SIZE)
    _manual(emu)
    emu.camera.set("gain", 8.0)  # push the white patch toward the top of the range
    _show_and_wait(emu, WHITE)
    f = emu.camera.grab()
    assert f.image.shape == shape
    assert f.image.dtype == dtype
    assert f.bits == bits and f.linear is linear
    assert int(f.image.max()) <= (1 << bits) - 1
    assert int(f.image.max()) > (1 << bits) // 4  # the codes use the range
    assert emu.camera.resolution == (shape[1], shape[0])
    assert emu.camera.channels == (1 if len(shape) == 2 else 3)


def test_clock_advances_with_the_devices() -> None:
    emu = open_emulator("mono12", "white", seed=0, projector_size=SIZE)
    emu.clock.sleep(0.1)
    assert emu.clock.now() == pytest.approx(0.1)
    t = emu.projector.show(WHITE)
    assert t > 0.1 and t - 0.1 <= P + 1e-9
    assert abs(t / P - round(t / P)) < 1e-6  # a swap happens at a vertical blank
    assert emu.clock.now() == pytest.approx(t)
    emu.camera.set("exposure", 0.01)
    before = emu.clock.now()
    f = emu.camera.grab()
    assert f.timestamp == pytest.approx(before)
    assert emu.clock.now() - before == pytest.approx(0.01 + MONO12.frame_interval)
    dslr = open_emulator("dslr", "white", seed=0, projector_size=SIZE)
    before = dslr.clock.now()
    dslr.camera.grab()
    assert 0.5 <= dslr.clock.now() - before <= 1.0  # a slow stills camera


def _first_lit(emu: Emulator, t_swap: float, periods: int = 7) -> int:
    """Refreshes after the swap at which an exposure starting at a refresh first sees the
    white light."""
    levels = []
    for k in range(periods):
        emu.clock.advance_to(t_swap + k * P)
        levels.append(float(emu.camera.grab().image.mean()))
    lit = np.asarray(levels) > 0.5 * max(levels)
    assert lit[-1] and not lit[0]
    return int(np.argmax(lit))


@pytest.mark.parametrize("seed", [0, 1, 2, 3, 4, 5])
def test_latency_is_two_to_four_refreshes(seed: int) -> None:
    emu = open_emulator("mono12", "white", seed=seed, projector_size=SIZE)
    emu.camera.set("exposure", P / 2)  # + the readout: each shot ends within its refresh
    _show_and_wait(emu, BLACK)
    _next_period(emu)
    t_swap = emu.projector.show(WHITE)
    k = _first_lit(emu, t_swap)
    assert 2 <= k <= 4
    assert k == emu.truth.latency


def test_latency_differs_between_devices() -> None:
    found = {
        open_emulator("mono12", "white", seed=s, projector_size=SIZE).truth.latency
        for s in range(12)
    }
    assert found <= {2, 3, 4} and len(found) > 1


def _lit_mean(image: np.ndarray, mask: np.ndarray) -> np.ndarray:
    return image.reshape(-1, image.shape[-1])[mask.ravel()].astype(np.float64).mean(axis=0)


def _exposure_pair(emu: Emulator, image: np.ndarray, exposure: float) -> np.ndarray:
    """image - black, each exposed ``exposure`` s from the start of a refresh period: (H, W, 3)."""
    out = []
    emu.camera.set("exposure", exposure)
    for pattern in (image, BLACK):
        _show_and_wait(emu, pattern)
        _next_period(emu)
        out.append(emu.camera.grab().image.astype(np.float64))
    return out[0] - out[1]


def test_dlp_partial_exposure_sees_a_partial_colour_sum() -> None:
    emu = open_emulator("dslr", "white", seed=5, projector_size=SIZE)
    model = emu.truth.model
    assert model.sequence == "RGBRGB" and model.spoke == pytest.approx(0.04)
    full = _exposure_pair(emu, WHITE, P)
    quarter = _exposure_pair(emu, WHITE, P / 4)
    lit = full.mean(axis=2) > 0.6 * np.percentile(full.mean(axis=2), 99)
    f, q = _lit_mean(full, lit), _lit_mean(quarter, lit)
    # by hand: six equal segments R G B R G B per period, each dark for its first 4% (the
    # spoke); full white lights every active part. A window [0, P/4] holds R's first segment
    # (active 0.96 P/6) and G's first segment from its spoke's end to P/4; no blue. A primary
    # is active 2 x 0.96 / 6 of the period, so it shines 1 / that while active: a whole
    # period integrates (1 - leak) P of it over black.
    seg = P / 6
    active = np.array([0.96 * seg, P / 4 - seg - 0.04 * seg, 0.0])
    duty = 2 * 0.96 / 6
    leak = np.asarray(model.leak)
    quarter_primaries = (1 - leak) * active / duty
    full_primaries = (1 - leak) * P
    mix = emu.truth.mixing
    expected = (mix @ quarter_primaries) / (mix @ full_primaries)
    np.testing.assert_allclose(q / f, expected, rtol=0.03, atol=0.003)
    assert q[2] / f[2] < 0.1 < 0.4 < q[0] / f[0]  # a wrong colour mix: red-heavy, no blue


def test_dlp_one_refresh_sees_grey_as_grey() -> None:
    emu = open_emulator("dslr", "white", seed=6, projector_size=SIZE)
    one = _exposure_pair(emu, GREY, P)
    three = _exposure_pair(emu, GREY, 3 * P)
    lit = three.mean(axis=2) > 0.6 * np.percentile(three.mean(axis=2), 99)
    a, b = _lit_mean(one, lit), _lit_mean(three, lit)
    np.testing.assert_allclose(a, b / 3, rtol=0.02)  # the same colour, a third of the light
    # and not what part of a period gives (R G B R: red counted twice)
    part = _lit_mean(_exposure_pair(emu, GREY, 4 * P / 6), lit)
    chroma = lambda v: v / v.sum()  # noqa: E731
    assert np.abs(chroma(part) - chroma(b)).max() > 0.05
    assert np.abs(chroma(a) - chroma(b)).max() < 0.005


def test_rolling_shutter_mixes_rows_after_a_change() -> None:
    emu = open_emulator("webcam", "white", seed=3, projector_size=SIZE, camera_size=(320, 180))
    _manual(emu)
    exposure = emu.camera.set("exposure", 0.002)
    gain = emu.camera.set("gain", 4.0)
    assert exposure == pytest.approx(0.002) and gain == 4.0
    _show_and_wait(emu, BLACK, 20)
    # frames start every 1/30 s = 2 P from 0; make the light change one refresh into a frame
    lat = emu.truth.latency
    t_light = (math.floor(emu.clock.now() / (2 * P)) + 3) * 2 * P + P
    emu.clock.advance_to(t_light - (lat + 1) * P + 1e-4)
    assert emu.projector.show(WHITE) == pytest.approx(t_light - lat * P)
    frame_start = t_light - P
    frames = {}
    for _ in range(12):
        f = emu.camera.grab()
        frames[round(f.timestamp / P)] = f
    k = round(frame_start / P)
    assert {k - 2, k, k + 2} <= set(frames)
    before, mixed, after = (frames[j].image.mean(axis=2) for j in (k - 2, k, k + 2))
    rows_lit = np.flatnonzero(after.mean(axis=1) > 0.5 * after.mean(axis=1).max())
    # rows start readout / (Hc - 1) apart: row r integrates [start + r dt, + exposure]; it
    # is dark while that window ends before t_light and fully lit once it starts after
    dt = WEBCAM.readout / (180 - 1)
    last_dark = math.floor((t_light - frame_start - exposure) / dt)
    first_full = math.ceil((t_light - frame_start) / dt)
    assert rows_lit[0] + 5 < last_dark < first_full < rows_lit[-1] - 5
    # against the frames before and after: same rows, same sub-frames
    ratio = (mixed - before).mean(axis=1) / (after - before).mean(axis=1)
    margin = 3  # the webcam's denoising and sharpening spread a row over its neighbours
    assert ratio[rows_lit[0] + margin : last_dark - margin].max() < 0.1
    np.testing.assert_allclose(ratio[first_full + margin : rows_lit[-1] - margin], 1.0, atol=0.08)
    band = ratio[last_dark + 1 : first_full]
    assert 0.2 < band.mean() < 0.8


def test_auto_exposure_drifts_until_locked() -> None:
    emu = open_emulator("webcam", "magenta", seed=4, projector_size=SIZE)
    assert emu.camera.get("auto_exposure") == 1
    _show_and_wait(emu, GREY)
    on = [emu.camera.grab().exposure for _ in range(10)]
    assert len(set(on)) > 3  # it keeps moving
    emu.camera.set("auto_exposure", 0)
    t_lock = emu.clock.now()
    locked = emu.camera.get("exposure")
    frames = [emu.camera.grab() for _ in range(12)]
    after = [f.exposure for f in frames if f.timestamp > t_lock]
    assert len(after) >= 6
    assert set(after) == {locked}
    assert emu.camera.get("exposure") == locked
    # and a manual exposure is ignored while auto exposure is on
    emu.camera.set("auto_exposure", 1)
    emu.camera.grab()
    asked = 0.0123
    assert emu.camera.set("exposure", asked) != pytest.approx(asked)


def test_auto_white_balance_drifts_until_locked() -> None:
    emu = open_emulator("webcam", "magenta", seed=8, projector_size=SIZE)
    emu.camera.set("auto_exposure", 0)
    _show_and_wait(emu, GREY, 30)

    def ratio(f) -> float:
        m = f.image.reshape(-1, 3).astype(np.float64).mean(axis=0)
        return m[0] / m[2]

    on = [ratio(emu.camera.grab()) for _ in range(8)]
    emu.camera.set("auto_white_balance", 0)
    t_lock = emu.clock.now()
    off = [ratio(f) for f in (emu.camera.grab() for _ in range(14)) if f.timestamp > t_lock]
    assert np.ptp(on) > 3 * np.ptp(off)


@pytest.mark.parametrize(
    ("profile", "asked", "got"),
    [
        ("webcam", 0.01234, 0.0123),  # V4L2: 100 us steps
        ("webcam", 5.0, 0.5),  # clamped to the driver's range
        ("webcam", 0.0, 0.0001),
        ("mono12", 0.00123456, 0.001235),  # 1 us steps
        ("dslr", 0.0123456, 0.0123456),  # any value
    ],
)
def test_exposure_steps_round_trip(profile: str, asked: float, got: float) -> None:
    emu = open_emulator(profile, "white", seed=0, projector_size=SIZE)
    _manual(emu)
    assert emu.camera.set("exposure", asked) == pytest.approx(got, rel=1e-9)
    assert emu.camera.get("exposure") == pytest.approx(got, rel=1e-9)
    assert emu.camera.set("exposure", got) == pytest.approx(got, rel=1e-9)
    rng = emu.camera.controls()["exposure"]
    assert rng.low <= got <= rng.high


def test_unknown_control_is_refused() -> None:
    from viewcomp.calib.hw.interface import DeviceError

    emu = open_emulator("mono12", "white", seed=0, projector_size=SIZE)
    with pytest.raises(DeviceError, match="white_balance"):
        emu.camera.set("white_balance", 5000)


def test_mjpeg_artefacts() -> None:
    from viewcomp.calib.io.patterns import chessboard

    board = chessboard(W, H)[0]
    frames = []
    for profile in (WEBCAM, replace(WEBCAM, mjpeg_quality=0)):
        emu = open_emulator(profile, "white", seed=9, projector_size=SIZE, camera_size=(320, 184))
        _manual(emu)
        _show_and_wait(emu, board, 20)
        frames.append([emu.camera.grab().image for _ in range(6)][-1].astype(np.float64))
    jpeg, plain = frames
    d = (jpeg - plain).mean(axis=2)
    assert 0.2 < np.abs(d).mean() < 6  # artefacts, and small ones
    # JPEG codes 8x8 blocks independently: its error jumps at block edges
    steps = np.abs(np.diff(d, axis=1)).mean(axis=0)  # steps[j]: between columns j and j + 1
    at_edges = steps[7::8].mean()
    inside = np.delete(steps, np.s_[7::8]).mean()
    assert at_edges > 1.3 * inside


def test_mono12_noise_matches_the_profile() -> None:
    emu = open_emulator("mono12", "white", seed=10, projector_size=SIZE)
    gain = emu.camera.set("gain", 2.0)
    emu.camera.set("exposure", 2 * P)  # whole periods: the same light in both frames
    _show_and_wait(emu, GREY)
    a, b = (emu.camera.grab().image.astype(np.float64) for _ in range(2))
    mean, var = (a + b) / 2, (a - b) ** 2 / 2
    top = (1 << MONO12.raw_bits) - 1
    dn_per_e = gain * top / MONO12.full_well
    for lo, hi in ((20, 200), (500, 3500)):  # room light only (read noise matters); lit
        sel = (mean > lo) & (mean < hi)
        assert sel.sum() > 500
        e = mean[sel] / dn_per_e
        expected = dn_per_e**2 * (e + MONO12.read_noise**2)
        assert var[sel].mean() == pytest.approx(expected.mean(), rel=0.15)


def test_webcam_frames_are_queued_and_stale() -> None:
    emu = open_emulator("webcam", "white", seed=11, projector_size=SIZE)
    _manual(emu)
    _show_and_wait(emu, BLACK, 30)
    t = emu.projector.show(WHITE)
    emu.clock.sleep(0.5)
    f = emu.camera.grab()
    assert f.timestamp < t  # the oldest of the four queued frames, exposed before the show
    seqs = [f.sequence] + [emu.camera.grab().sequence for _ in range(3)]
    assert seqs == list(range(seqs[0], seqs[0] + 4))
    nxt = emu.camera.grab()
    assert nxt.sequence > seqs[-1] + 1  # the driver dropped frames while its queue was full


def _shift_x(a: np.ndarray, b: np.ndarray) -> float:
    """Horizontal shift of image b relative to a (camera px, + = right)."""
    (dx, _), _ = cv2.phaseCorrelate(a.astype(np.float64), b.astype(np.float64))
    return dx


def test_bump_moves_the_image_from_show_k_on() -> None:
    emu = open_emulator(
        "mono12", "white", seed=12, projector_size=SIZE, faults=Faults(bump_at=(3, 4.0))
    )
    from viewcomp.calib.io.patterns import chessboard

    board = chessboard(W, H)[0]
    images = []
    for _ in range(6):  # show indices 0..5; the bump happens at index 3
        _show_and_wait(emu, board)
        images.append(emu.camera.grab().image)
    for k in (1, 2):
        assert abs(_shift_x(images[0], images[k])) < 0.2
    for k in (3, 4, 5):
        assert _shift_x(images[0], images[k]) == pytest.approx(-4.0, abs=0.6)


def test_dropped_frames_leave_sequence_gaps() -> None:
    for profile in ("webcam", "mono12"):
        emu = open_emulator(
            profile, "white", seed=13, projector_size=SIZE, faults=Faults(drop_at=(2,))
        )
        seqs = [emu.camera.grab().sequence for _ in range(5)]
        gaps = np.diff(seqs)
        assert list(gaps) == [1, 2, 1, 1], profile


def test_failed_reads_raise_frame_error_where_injected() -> None:
    emu = open_emulator(
        "mono12", "white", seed=14, projector_size=SIZE, faults=Faults(fail_at=(1, 3))
    )
    outcome = []
    for _ in range(5):
        try:
            emu.camera.grab()
            outcome.append("ok")
        except FrameError:
            outcome.append("fail")
    assert outcome == ["ok", "fail", "ok", "fail", "ok"]
    emu = open_emulator("mono12", "white", seed=15, projector_size=SIZE, faults=Faults(fail_p=0.3))
    fails = 0
    for _ in range(200):
        try:
            emu.camera.grab()
        except FrameError:
            fails += 1
    assert 35 <= fails <= 85


def test_late_frame_comes_one_refresh_later() -> None:
    emu = open_emulator(
        "mono12", "white", seed=16, projector_size=SIZE, faults=Faults(late_at=(2,))
    )
    emu.camera.set("exposure", P / 2)
    found = []
    for image in (WHITE, BLACK, WHITE, BLACK):  # show indices 0..3; index 2 is late
        _next_period(emu, 2)
        t = emu.projector.show(image)
        found.append(_first_change(emu, t, image is WHITE))
        emu.clock.sleep(8 * P)
    lat = emu.truth.latency
    assert found == [lat, lat, lat + 1, lat]


def _first_change(emu: Emulator, t_swap: float, to_white: bool) -> int:
    levels = []
    for k in range(7):
        emu.clock.advance_to(t_swap + k * P)
        levels.append(float(emu.camera.grab().image.mean()))
    v = np.asarray(levels)
    mid = (v.max() + v.min()) / 2
    changed = v > mid if to_white else v < mid
    return int(np.argmax(changed))


def test_fault_parsing() -> None:
    f = parse_faults("bump=20:3,fail=5+9, late_p=0.05,drop=2")
    assert f == Faults(bump_at=(20, 3.0), fail_at=(5, 9), late_p=0.05, drop_at=(2,))
    assert parse_faults("") == Faults()
    assert parse_bump("7:-2.5") == (7, -2.5)
    for bad in ("bogus=1", "bump=3", "fail=a", "late_p=2", "drop=-1"):
        with pytest.raises(FaultSpecError):
            parse_faults(bad)


def test_screens_swap_and_materials(materials_dir) -> None:
    emu = open_emulator("mono12", materials_dir / "red-plastic.npz", seed=17, projector_size=SIZE)
    emu.camera.set("exposure", 2 * P)
    _show_and_wait(emu, GREY)
    white = emu.camera.grab().image.astype(np.float64).mean()
    emu.swap_screen("screen")
    _show_and_wait(emu, GREY)
    red = emu.camera.grab().image.astype(np.float64).mean()
    assert red < 0.8 * white
    with pytest.raises(ValueError, match="no emulated screen"):
        emu.swap_screen("wall")
    assert set(PROFILES) == {"webcam", "dslr", "mono12"}


def test_dlp_white_segment_adds_light_to_white_only() -> None:
    from viewcomp.calib.emu.dlp import DlpModel

    dlp = DlpModel(sequence="RGBW", white_gain=0.3)
    emu = open_emulator("dslr", "white", seed=18, projector_size=SIZE, dlp=dlp)
    white = _exposure_pair(emu, WHITE, P)
    lit = white.mean(axis=2) > 0.6 * np.percentile(white.mean(axis=2), 99)
    primaries = 0
    for c in range(3):
        one = np.zeros_like(WHITE)
        one[..., c] = 255
        primaries = primaries + _lit_mean(_exposure_pair(emu, one, P), lit)
    # by hand: over a whole period each primary at 255 gives (1 - leak) over black; the
    # white segment at min(R, G, B) = 255 adds white_gain of every primary, only for white
    mix, leak = emu.truth.mixing, np.asarray(dlp.leak)
    expected = (mix @ (1 - leak) + 0.3 * mix @ np.ones(3)) / (mix @ (1 - leak))
    np.testing.assert_allclose(_lit_mean(white, lit) / primaries, expected, rtol=0.02)


def test_truth_sees_the_steady_light() -> None:
    emu = open_emulator("webcam", "white", seed=19, projector_size=SIZE)
    sim = emu.truth.simulator
    eye = emu.truth.rig.viewer.eye(70.0)
    got = emu.truth.observe_linear("white", WHITE, eye)
    # by hand: full white is every primary at full light (leak + (1 - leak) * 1 = 1) on a
    # matte white board of albedo 0.85, seen at the simulator's exposure 0.8
    ambient = np.array([0.015, 0.015, 0.018])
    expected = 0.8 * 0.85 * (sim.falloff[..., None] * emu.truth.mixing.sum(axis=1) + ambient)
    np.testing.assert_allclose(got, expected, rtol=1e-6)
    assert got.shape == (H, W, 3)
