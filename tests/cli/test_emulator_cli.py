"""`viewcomp capture --emulate`: the real capture procedure on the emulated devices, and the
options that inject faults."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.support.materials import MEASURED
from viewcomp.calib.world.rig import load_rig
from viewcomp.cli import main


def _on_material(out: Path, profile: str, material: str, *extra: str) -> list[str]:
    """`viewcomp capture OUT --emulate PROFILE --material M` at 160x80, 2 frames, seed 0."""
    argv = ["capture", str(out), "--emulate", profile, "--material", material]
    return [*argv, "--sim-size", "160x80", "--frames", "2", "--seed", "0", "--yes", *extra]


@pytest.mark.parametrize(
    ("argv", "said"),
    [
        (["--simulate", "--bump-at", "3:2"], "add --emulate"),
        (["--simulate", "--faults", "fail=2"], "add --emulate"),
        (["--simulate", "--emulate", "webcam"], "give one"),
        (["--emulate", "webcam", "--bump-at", "3"], "--bump-at: a bump is K:PX"),
        (["--emulate", "webcam", "--faults", "bogus=1"], "--faults: unknown fault"),
        (["--emulate", "webcam", "--faults", "fail_p=2"], "fail_p is a probability"),
    ],
)
def test_emulator_usage_errors(tmp_path: Path, capsys, argv: list[str], said: str) -> None:
    out = tmp_path / "caps"
    with pytest.raises(SystemExit) as e:
        main(["capture", str(out), "--yes", "--sim-size", "160x80", *argv])
    assert e.value.code == 2
    assert said in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.slow
def test_a_bumped_camera_is_refused(tmp_path: Path, capsys) -> None:
    out = tmp_path / "caps"
    argv = ["capture", str(out), "--emulate", "webcam", "--sim-size", "160x80", "--yes"]
    # a fixed exposure: --bump-at counts every pattern shown, the exposure search's included,
    # and K = 20 is to land among the captures compared with gray
    argv += ["--exposure", "0.0333"]
    assert main([*argv, "--seed", "3", "--frames", "2", "--bump-at", "20:3"]) == 2
    err = capsys.readouterr().err
    assert "camera moved (or was bumped)" in err and "emulated devices' clock" in err
    assert not out.exists()


@pytest.mark.slow
def test_dslr_capture_end_to_end(tmp_path: Path, capsys) -> None:
    out = tmp_path / "caps"
    argv = ["capture", str(out), "--emulate", "dslr", "--sim-size", "160x80", "--yes"]
    assert main([*argv, "--seed", "1", "--frames", "2", "--faults", "fail=5+9"]) == 0
    rig = load_rig(out / "rig.toml")
    assert rig.camera.response == "linear" and rig.camera.resolution == (640, 360)
    assert rig.projector.resolution == (160, 80)
    assert "a read failed" in capsys.readouterr().err  # retried, not fatal


@pytest.mark.slow
@pytest.mark.parametrize("profile", ["webcam", "mono12"])
def test_hdr_on_a_camera_whose_white_needs_a_period_or_two_is_bracketed_upward(
    tmp_path: Path, capsys, profile: str
) -> None:
    """A 60 Hz webcam (or machine-vision camera) whose white screen needs one or two refresh
    periods has no shorter stop in whole periods: the bracket goes upward from one period
    and the set is written as linear .npy captures."""
    out = tmp_path / "c"
    argv = ["capture", str(out), "--emulate", profile, "--sim-size", "160x80", "--frames", "2"]
    assert main([*argv, "--yes", "--hdr"]) == 0, capsys.readouterr().err
    err = capsys.readouterr().err
    assert "HDR bracket: taken upward" in err, err
    assert (out / "screen" / "graycode_00.npy").is_file()
    assert (out / "white" / "gray.npy").is_file()


@pytest.mark.slow
def test_a_highlight_one_refresh_period_clips_is_taken_with_the_projector_dimmed(
    tmp_path: Path, capsys, materials_dir: Path
) -> None:
    """mono12 on green plastic: its highlight clipped even in the one-period stop at gain 1
    (1.7 % of the lit pixels, refused before); the clipped captures are taken again with the
    pattern dimmed and the set is written and calibrates."""
    out = tmp_path / "c"
    material = str(materials_dir / "green-plastic.npz")
    argv = _on_material(out, "mono12", material, "--hdr")
    assert main(argv) == 0, capsys.readouterr().err
    err = capsys.readouterr().err
    assert "the projector's drive dimmed" in err, err
    assert "clipped pixel-channels recovered" in err
    assert "were taken again with the projector dimmed" in err
    assert main(["calibrate", str(out), "-o", str(tmp_path / "b.npz")]) == 0


MATERIALS = MEASURED


@pytest.mark.slow
@pytest.mark.parametrize("hdr", [False, True], ids=["8bit", "hdr"])
@pytest.mark.parametrize("name", MATERIALS)
def test_the_webcam_on_a_measured_material_is_not_refused_as_moved(
    tmp_path: Path, capsys, materials_dir: Path, name: str, hdr: bool
) -> None:
    """The emulated webcam (MJPEG, Bayer, S-curve, rolling shutter, 0.6 camera px per
    projector px) on each measured material: no camera-moved refusal (bluebook's ramp was
    "moved" 20-23 px, satin_gold's 20 px at 160x80); 8 bits may be refused for clipping
    only, naming --hdr; with --hdr the set is written, and bluebook's calibrates."""
    material = materials_dir / f"{name}.npz"
    if not material.is_file():
        pytest.skip(f"measured material {material.name} not in {materials_dir}")
    out = tmp_path / "c"
    argv = _on_material(out, "webcam", str(material))
    rc = main([*argv, "--hdr"] if hdr else argv)
    err = capsys.readouterr().err
    assert not any(w in err for w in ("moved", "lies ", "no clear match")), err
    if hdr:
        assert rc == 0, err
    elif rc != 0:
        assert "saturated" in err and "--hdr" in err, err
    if hdr and name == "bluebook":
        assert main(["calibrate", str(out), "-o", str(tmp_path / "b.npz")]) == 0


@pytest.mark.slow
def test_a_dslr_whose_shortest_stop_clips_takes_it_with_the_projector_dimmed(
    tmp_path: Path, capsys, materials_dir: Path
) -> None:
    """The DSLR on bluebook: its bracket goes downward (83 ms and 1/4 of it), and the
    highlight clips even in the 1/4 stop (refused as "clipped even in the shortest bracket
    stop" before the dimmed stops); the clipped captures are taken again at that stop with
    the pattern dimmed, and the set is written and calibrates."""
    out = tmp_path / "c"
    material = str(materials_dir / "bluebook.npz")
    argv = _on_material(out, "dslr", material, "--hdr")
    assert main(argv) == 0, capsys.readouterr().err
    err = capsys.readouterr().err
    assert "HDR bracket: relative exposures 1, 1/4 " in err, err
    assert "the projector's drive dimmed" in err, err
    assert "were taken again with the projector dimmed" in err
    assert main(["calibrate", str(out), "-o", str(tmp_path / "b.npz")]) == 0
