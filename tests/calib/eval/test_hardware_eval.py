"""evaluate --protocol hardware (calib/eval/hardware.py): the real capture procedure on the
emulated devices, end to end, beside ideal captures."""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Any

import pytest

from viewcomp.calib.emu.emulator import open_emulator
from viewcomp.calib.eval.hardware import (
    WITHIN,
    check_hardware,
    emulated_capture,
    hardware_case,
    ideal_calibration,
    seen_errors,
)
from viewcomp.calib.eval.testimages import natural_images
from viewcomp.calib.fit.calibrate import Calibration, calibrate
from viewcomp.calib.io.captureset import read_capture_set


def _row(profile: str, emulated: float, ideal: float, refused: str | None = None) -> dict:
    cell = {"compensated": emulated, "original": 30.0}
    ref = {"compensated": ideal, "original": 30.0}
    return {
        "profile": profile, "screen": "magenta", "capture": "8bit", "refused": refused,
        "emulated": {a: cell for a in ("60", "90", "125")},
        "ideal": {a: ref for a in ("60", "90", "125")},
    }  # fmt: skip


def test_the_criteria_count_refusals_and_ratios() -> None:
    ok = check_hardware([_row("dslr", 11.0, 10.0)])
    assert ok["within"] and ok["ratios"]["dslr/magenta/8bit@60"] == pytest.approx(1.1)
    worse = check_hardware([_row("dslr", 10.0 * WITHIN + 0.1, 10.0)])
    assert not worse["within"]
    refused = check_hardware([_row("webcam", 0, 0, refused="camera moved")])
    assert refused["refused"] == ["webcam/magenta/8bit"] and not refused["within"]


def test_a_mono_row_is_held_to_the_ideal_mono_camera_and_shows_the_colour_one() -> None:
    """A mono camera's pipeline is the per-primary model: the criterion compares it with an
    ideal mono camera's; the ideal colour camera's ratio is reported beside, not judged."""
    row = _row("mono12", 11.0, 10.0)
    row["ideal_colour"] = {a: {"compensated": 5.0, "original": 30.0} for a in ("60", "90", "125")}
    checks = check_hardware([row])
    assert checks["within"], checks
    assert checks["ratios"]["mono12/magenta/8bit@60"] == pytest.approx(1.1)
    assert checks["ratios_colour"]["mono12/magenta/8bit@60"] == pytest.approx(2.2)
    assert check_hardware([_row("webcam", 11.0, 10.0)])["ratios_colour"] == {}


def test_the_ideal_mono_camera_sees_no_colour_mixing() -> None:
    """The ideal mono calibration is the per-primary model fitted from ideal mono captures:
    on the saturated glossy magenta it leaves far more error than the ideal colour camera
    (whose W~ holds the surface's colour mixing), and it still compensates."""
    emu = open_emulator("mono12", "magenta", seed=0, projector_size=(160, 80))
    try:
        imgs = {"astronaut": natural_images(160, 80)["astronaut"]}
        mono_cal = ideal_calibration(emu, mono=True)
        assert "mono" in mono_cal.info
        mono = seen_errors(emu, mono_cal, imgs, (60.0,))["60"]
        colour = seen_errors(emu, ideal_calibration(emu), imgs, (60.0,))["60"]
    finally:
        emu.close()
    print(f"\nideal mono {mono}, ideal colour {colour}")
    assert colour["compensated"] * 1.5 < mono["compensated"] < mono["original"]


def _small_case(
    profile: str, screen: Path, hdr: bool, variants: dict[str, dict[str, Any]]
) -> tuple[dict[str, dict], dict, dict[str, Calibration]]:
    """``profile``'s emulated capture of ``screen`` at 160x80 (seed 0), calibrated once per
    variant (name -> :func:`calibrate` keywords): (per variant the errors seen at 60 and 125
    degrees on the astronaut, those of the ideal captures by a camera of the same kind, the
    calibrations)."""
    emu = open_emulator(profile, screen, seed=0, projector_size=(160, 80))
    imgs = {"astronaut": natural_images(160, 80)["astronaut"]}
    try:
        with tempfile.TemporaryDirectory(prefix="viewcomp-test-") as tmp:
            emulated_capture(emu, Path(tmp) / "caps", hdr=hdr)
            cs = read_capture_set(Path(tmp) / "caps")
            cals = {k: calibrate(cs, **kw) for k, kw in variants.items()}
        seen = {k: seen_errors(emu, c, imgs, (60.0, 125.0)) for k, c in cals.items()}
        mono = emu.camera.channels == 1
        ideal = seen_errors(emu, ideal_calibration(emu, mono=mono), imgs, (60.0, 125.0))
    finally:
        emu.close()
    return seen, ideal, cals


@pytest.mark.slow
def test_mono12_on_measured_spectralon_matches_an_ideal_mono_camera(materials_dir: Path) -> None:
    """A mono machine-vision camera's 8-bit-mode capture of a measured near-white material, in
    camera space: its three per-primary gains are separate noisy captures, and the colour
    noise they leave is what separates it from an ideal mono camera (a near-white screen's
    compensation shows every bit of it). With the gains' shares smoothed by the colour guide
    (calibrate's default for camera-space sets) it is within WITHIN of the ideal mono camera
    at 60 and 125 degrees; without the guide it is not."""
    variants = {"guided": {}, "plain": {"guide_px": 0}}
    seen, ideal, _ = _small_case("mono12", materials_dir / "spectralon.npz", False, variants)
    for a in ("60", "125"):
        i = ideal[a]["compensated"]
        g, p = seen["guided"][a]["compensated"] / i, seen["plain"][a]["compensated"] / i
        print(f"\nmono12 spectralon {a} deg: guided {g:.3f}, without {p:.3f} of ideal mono")
        # measured: 1.01 / 0.99 guided, 1.48 / 1.44 without (60 / 125 degrees)
        assert g <= WITHIN
        assert p > WITHIN


@pytest.mark.slow
def test_a_webcam_measures_the_colour_mixing_better_with_a_larger_rise(
    materials_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The emulated webcam (8 bits, MJPEG) on a measured near-white material: its colour
    patterns at CAMERA_COLOUR_LEVEL (what `capture` shows) give a compensation closer to the
    white screen than Table 1's 130, whose 20-level rise leaves the cross-talk within the
    codec's chroma quantisation."""
    import viewcomp.calib.hw.plan as plan

    imgs = {"astronaut": natural_images(160, 80)["astronaut"]}
    seen = {}
    for level in (plan.CAMERA_COLOUR_LEVEL, 130):
        monkeypatch.setattr(plan, "CAMERA_COLOUR_LEVEL", level)
        emu = open_emulator(
            "webcam", materials_dir / "spectralon.npz", seed=0, projector_size=(160, 80)
        )
        try:
            with tempfile.TemporaryDirectory(prefix="viewcomp-test-") as tmp:
                emulated_capture(emu, Path(tmp) / "caps", hdr=False)
                cal = calibrate(read_capture_set(Path(tmp) / "caps"))
                seen[level] = seen_errors(emu, cal, imgs, (60.0, 125.0))
        finally:
            emu.close()
    for a in ("60", "125"):
        big, small = seen[255][a]["compensated"], seen[130][a]["compensated"]
        print(f"\nwebcam spectralon {a} deg: rise to 255 {big:.3f} dE, to 130 {small:.3f}")
        # measured at the default 16 frames: 0.729 vs 0.881 (60 deg), 0.761 vs 0.847 (125 deg)
        assert big < 0.95 * small


@pytest.mark.slow
def test_dslr_capture_on_glossy_magenta_matches_ideal_captures() -> None:
    """The DSLR profile (raw linear, slow, high resolution) through the whole procedure:
    calibrated, and the viewer's error within WITHIN of the ideal captures' at 60 and 125
    degrees; the capture takes real-device time on the emulated clock (seconds, not the
    milliseconds an instant fake would report)."""
    row: dict[str, Any] = hardware_case(
        "dslr", "magenta", "8bit", size=(160, 80), image_names=("astronaut",)
    )
    assert row["refused"] is None, row["refused"]
    checks = check_hardware([row])
    print(f"\ndslr magenta 8-bit: {checks['ratios']}, capture {row['capture_seconds']} s")
    assert checks["within"], checks
    assert row["capture_seconds"] > 30.0
    for a in ("60", "125"):  # compensation helps at all
        assert row["emulated"][a]["compensated"] < row["emulated"][a]["original"]


@pytest.mark.slow
def test_a_coarse_webcam_reads_a_still_falling_lobe_past_its_edge_zone(materials_dir: Path) -> None:
    """The emulated webcam (0.6 camera px per projector px) in HDR on measured satin_gold,
    whose lobe is still falling at the frame's farthest angles: the frame's edge zone holds
    copies of inner values there. Fitted as measurements they held the lobe's baseline at the
    level of nearer angles (1.46 / 1.42 times the ideal captures' dE at 60 / 125 degrees at
    this size, measured); left out and continued, 1.16 / 1.11."""
    seen, ideal, cals = _small_case("webcam", materials_dir / "satin_gold.npz", True, {"": {}})
    assert "edge zone" in cals[""].pixel.lobe.message
    for a in ("60", "125"):
        ratio = seen[""][a]["compensated"] / ideal[a]["compensated"]
        print(f"\nwebcam satin_gold HDR 160x80 at {a} deg: {ratio:.3f} of the ideal captures' dE")
        assert ratio < 1.25


def test_the_protocol_says_its_rows_and_the_time_left(monkeypatch) -> None:
    """A run of 48 rows takes an hour or more: after each row it says how many are done and
    about how long the rest takes."""
    import viewcomp.calib.eval.hardware as hw

    def fake_case(profile: str, screen: str, capture: str, *args: Any, **kw: Any) -> dict:
        return _row(profile, 11.0, 10.0)

    monkeypatch.setattr(hw, "hardware_case", fake_case)
    said: list[str] = []
    rep = hw.hardware(["magenta", "m.npz"], profiles=("webcam", "dslr"), progress=said.append)
    assert len(rep["hardware"]) == 8
    counts = [line.split()[1] for line in said]
    assert counts == [f"{i}/8" for i in range(1, 9)], said
    assert all("min left" in line for line in said)
