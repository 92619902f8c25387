"""Projector-dimmed HDR stops: what one refresh period at gain 1 clips is recovered from the
pattern shown again with its drive dimmed, at a light ratio measured in the capture.

The truth is the emulator's physics, not the dimming's convention: the noise-free signal the
emulated camera integrates over whole refresh periods of the DLP (its offset power law with a
large toe, leak and per-primary gammas), blurred by its optics, at the bracket's base exposure
where no sensor clips it."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest

from viewcomp.calib.emu.camera import MONO_WEIGHTS
from viewcomp.calib.emu.dlp import DlpModel
from viewcomp.calib.emu.emulator import Emulator, open_emulator
from viewcomp.calib.emu.profiles import MONO12, CameraProfile
from viewcomp.calib.hw.dimming import (
    DRIVE_STEP,
    Dimmer,
    dimmed,
    fill_clipped,
    measured_ratio,
    single_level,
    weighted_median,
)
from viewcomp.calib.hw.reader import FrameReader
from viewcomp.calib.hw.session import Session
from viewcomp.calib.io.hdr import DEFAULT_STOPS
from viewcomp.calib.io.patterns import table1_patterns
from viewcomp.calib.world.response import parse_response

P = 1.0 / 60.0
SIZE = (160, 80)
#: A projector far from a power law: a toe three times the emulator's default.
DLP = DlpModel(toe=0.15)
#: mono12 five times as sensitive: white on the glossy magenta screen clips in its highlight
#: at one refresh period and gain 1 (the truth peaks at 1.3 of full scale), not elsewhere.
BRIGHT_MONO = replace(MONO12, nominal_exposure=MONO12.nominal_exposure / 5.0)


def _session(lines: list[str], profile: CameraProfile) -> tuple[Emulator, Session]:
    emu = open_emulator(profile, "magenta", seed=0, projector_size=SIZE, dlp=DLP)
    emu.camera.set("exposure", P)
    emu.camera.set("gain", 1.0)
    reader = FrameReader(emu.camera, emu.clock, lines.append)
    session = Session(emu.projector, emu.camera, emu.clock, reader, lines.append, 2, 0.0)
    session.prepare(False, DEFAULT_STOPS, parse_response("linear"), False)
    emu.swap_screen("screen")
    w, h = SIZE
    session.take(np.zeros((h, w, 3), np.uint8), "screen/black")
    return emu, session


def _truth(
    emu: Emulator, image: np.ndarray, exposure: float, profile: CameraProfile = BRIGHT_MONO
) -> np.ndarray:
    """The emulated mono camera's noise-free signal (Hc, Wc) of ``image`` over ``exposure``
    seconds of whole refresh periods (relative codes, unclipped)."""
    luts = DLP.drive_luts(np.array([0.0]), np.array([exposure]))
    scene = emu.camera.scenes[0]
    screen = emu.truth.screens["screen"]
    integral = scene.integrate(screen, [(10**6 + int(image.sum()), image, luts)], exposure)
    sig = np.asarray(integral * np.float32(profile.sensitivity), np.float32)
    sig = cv2.GaussianBlur(sig, (0, 0), profile.blur_px, borderType=cv2.BORDER_REFLECT)
    return sig @ MONO_WEIGHTS


def _before_and_after(
    pattern: np.ndarray, profile: CameraProfile = BRIGHT_MONO
) -> tuple[Emulator, Session, tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]:
    lines: list[str] = []
    emu, session = _session(lines, profile)
    assert session.bracket is not None and session.dimmer is not None
    merged = session.bracket.grab(2, session._show(pattern), "screen/pattern")
    after = session.dimmer.recover(pattern, merged, session.black, 2, "screen/pattern")
    return emu, session, merged, after


def test_a_dimmed_stop_recovers_the_highlight_through_a_non_ideal_projector() -> None:
    w, h = SIZE
    white = np.full((h, w, 3), 255, np.uint8)
    emu, session, (_, clipped), (lin, left) = _before_and_after(white)
    was = clipped[..., 0]
    assert was.sum() > 500  # the highlight clips at one period: the case this is about
    assert not left.any()
    truth = _truth(emu, white, P)  # the base is one period at gain 1
    err = lin[..., 0][was] / truth[was] - 1.0
    assert abs(float(np.median(err))) < 0.02
    assert float(np.percentile(np.abs(err), 90)) < 0.05
    # the ratio is the projector's, not the drive's: a power law of 2.2 would be 18 % off
    assert session.dimmer is not None
    ratio = session.dimmer.known[((255, 255, 255), 1)][0][0]
    assert abs(ratio / DRIVE_STEP**2.2 - 1.0) > 0.1
    lit = ~was & (truth > 0.2)
    assert abs(float(np.median(lin[..., 0][lit] / truth[lit] - 1.0))) < 0.01


@pytest.mark.slow
def test_a_pattern_of_many_levels_is_recovered_by_its_own_mean_ratio() -> None:
    # levels 160..255 down the rows (bright where the highlight is, as a phase-shifted
    # fringe's crest), a camera 8 times as sensitive as mono12: each level dims by its own
    # ratio (the toe), the recovery is approximate
    w, h = SIZE
    levels = np.rint(np.linspace(160, 255, h)).astype(np.uint8)
    ramp = np.repeat(np.repeat(levels[:, None, None], w, axis=1), 3, axis=2)
    brighter = replace(MONO12, nominal_exposure=MONO12.nominal_exposure / 8.0)
    emu, _, (_, clipped), (lin, left) = _before_and_after(ramp, brighter)
    was = clipped[..., 0]
    assert was.sum() > 50
    assert left.sum() < was.sum()
    truth = _truth(emu, ramp, P, brighter)
    fixed = was & ~left[..., 0]
    err = lin[..., 0][fixed] / truth[fixed] - 1.0
    assert abs(float(np.median(err))) < 0.08


def test_single_level_patterns_and_dimmed_drives() -> None:
    w, h = SIZE
    t1 = table1_patterns(w, h)
    assert single_level(t1["red"]) and single_level(t1["gray"])
    assert not single_level(t1["ramp"]) and not single_level(t1["black"])
    board = np.zeros((h, w, 3), np.uint8)
    board[:, : w // 2] = 255
    assert single_level(board)
    assert dimmed(board, 0.5)[0, 0].tolist() == [128, 128, 128]  # 127.5 rounds to even: 128
    assert dimmed(t1["red"], 0.25)[0, 0].tolist() == [32, 28, 28]  # 130, 110 -> 32.5, 27.5


def test_ratio_and_fill_recover_light_above_black() -> None:
    # a capture built by hand: black B, light above black A, dimmed by r = (0.2, 0.25, 0.3)
    rng = np.random.default_rng(1)
    black = rng.uniform(0.01, 0.03, (40, 60, 3)).astype(np.float32)
    above = rng.uniform(0.2, 0.9, (40, 60, 3)).astype(np.float32)
    above[10:14, 20:24] = 3.0  # a highlight: clipped in the capture
    r = np.array([0.2, 0.25, 0.3], np.float32)
    truth = black + above
    clipped = np.zeros(truth.shape, bool)
    clipped[10:14, 20:24] = True
    lin = np.where(clipped, 1.0, truth).astype(np.float32)
    dim_lin = black + above * r
    found, counts = measured_ratio(lin, clipped, dim_lin, np.clip(dim_lin, 0, 1), black)
    assert found == pytest.approx(r, rel=1e-5)
    assert (counts > 1000).all()
    out, left = fill_clipped(lin, clipped, dim_lin, np.zeros_like(clipped), black, found)
    assert not left.any()
    assert out == pytest.approx(truth, rel=1e-5)
    # without the black level the highlight would be off by B (1/r - 1): the test sees it
    wrong, _ = fill_clipped(lin, clipped, dim_lin, np.zeros_like(clipped), None, found)
    assert float(np.abs(wrong[10:14, 20:24] - truth[10:14, 20:24]).max()) > 0.02


def test_a_channel_too_small_to_measure_takes_the_earlier_ratio() -> None:
    h, w = 30, 40
    pattern = np.full((h, w, 3), 255, np.uint8)
    black = np.zeros((h, w, 3), np.float32)
    r_true = np.array([0.2, 0.22, 0.18], np.float32)
    shown: list[np.ndarray] = []

    def capture(lit_columns: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        light = np.zeros((h, w, 3), np.float32)
        light[:, :lit_columns] = 0.5
        light[5:8, 5:8] = 2.0
        clipped = light > 1.0
        return np.minimum(light, 1.0), clipped, light

    full_lin, full_clip, full_light = capture(w)
    narrow_lin, narrow_clip, narrow_light = capture(9)
    narrow_light[:, :, 1] = np.where(narrow_light[..., 1] < 1.0, 0.0, narrow_light[..., 1])
    current = {"light": full_light}

    def show(p: np.ndarray) -> float:
        shown.append(p)
        return 0.0

    def shortest(frames: int, not_before: float, what: str) -> tuple[np.ndarray, float]:
        dim = current["light"] * r_true
        return np.rint(np.clip(dim, 0, 1) * 65535).astype(np.uint16), 1.0

    dimmer = Dimmer(show, shortest, lambda: parse_response("linear"), lambda _: None)
    lin, left = dimmer.recover(pattern, (full_lin, full_clip), black, 1, "white")
    assert not left.any() and lin[6, 6] == pytest.approx([2.0] * 3, rel=1e-3)
    # a narrow lit part whose green channel is dark except the highlight: green is not
    # measurable there, so the white's ratio is used for it
    narrow_lin[..., 1] = np.minimum(narrow_light[..., 1], 1.0)
    current["light"] = narrow_light
    lin, left = dimmer.recover(pattern, (narrow_lin, narrow_clip), black, 1, "plane")
    assert not left.any()
    assert lin[6, 6] == pytest.approx([2.0] * 3, rel=1e-3)
    assert len(shown) == 2 and shown[0][0, 0].tolist() == [128, 128, 128]


def test_pixels_lit_only_by_the_room_do_not_measure_the_ratio() -> None:
    # a Gray-code plane whose lit stripes all clip: what is left unclipped is room light
    # (black B at 20 codes of 255) and a tenth of a code more that the dimming does not
    # change (a black capture taken a little earlier, a codec's ringing), plus noise; without
    # the black's codes those pixels pass the code threshold and measure a ratio near 1, with
    # them they measure nothing
    rng = np.random.default_rng(3)
    h, w = 40, 60
    black = np.full((h, w, 3), 20.0 / 255.0, np.float32)
    clipped = np.zeros((h, w, 3), bool)
    clipped[:, :20] = True  # the lit stripe
    dark = black + 0.1 / 255.0
    lin = np.where(clipped, 1.0, dark + rng.normal(0, 1e-4, (h, w, 3))).astype(np.float32)
    dim_lin = np.where(clipped, 0.8, dark + rng.normal(0, 1e-4, (h, w, 3))).astype(np.float32)
    codes = np.clip(dim_lin, 0, 1)
    fooled, n = measured_ratio(lin, clipped, dim_lin, codes, black)
    assert (n > 100).all() and np.all(fooled > 0.3)  # the test can see the bias
    found, counts = measured_ratio(lin, clipped, dim_lin, codes, black, black)
    assert np.isnan(found).all() and not counts.any()


def test_weighted_median() -> None:
    assert weighted_median(np.array([0.2, 0.9, 0.21]), np.array([1000, 2500, 1800])) == 0.21
    assert weighted_median(np.array([0.2, 0.9]), np.array([3, 1])) == 0.2
    assert weighted_median(np.array([0.2, np.nan, 0.5]), np.array([1, 9, 2])) == 0.5
    assert np.isnan(weighted_median(np.array([0.2]), np.array([0])))


def test_one_wrong_measurement_does_not_replace_the_others() -> None:
    # four planes of one drive triple: three measure the true ratio on about 1000 pixels
    # each, the fourth a wrong one (its unclipped part dims by 0.9: stray light) on 2400;
    # the fourth's highlight is still filled with the true ratio
    h, w = 40, 60
    pattern = np.full((h, w, 3), 255, np.uint8)
    black = np.zeros((h, w, 3), np.float32)
    r_true = 0.2
    current: dict[str, np.ndarray] = {}

    def shortest(frames: int, not_before: float, what: str) -> tuple[np.ndarray, float]:
        return np.rint(np.clip(current["dim"], 0, 1) * 65535).astype(np.uint16), 1.0

    dimmer = Dimmer(lambda p: 0.0, shortest, lambda: parse_response("linear"), lambda _: None)
    for unclipped_ratio, lit_rows in ((r_true, 17), (r_true, 17), (r_true, 17), (0.9, 40)):
        light = np.zeros((h, w, 3), np.float32)
        light[:lit_rows] = 0.5
        light[5:8, 5:8] = 2.0
        clipped = light > 1.0
        current["dim"] = np.where(clipped, light * r_true, light * unclipped_ratio)
        lin, left = dimmer.recover(pattern, (np.minimum(light, 1.0), clipped), black, 1, "p")
        assert not left.any()
        assert lin[6, 6] == pytest.approx([2.0] * 3, rel=1e-3)
