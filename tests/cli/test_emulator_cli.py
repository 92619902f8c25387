"""`viewcomp capture --emulate`: the real capture procedure on the emulated devices, and the
options that inject faults."""

from __future__ import annotations

from pathlib import Path

import pytest

from viewcomp.calib.world.rig import load_rig
from viewcomp.cli import main


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
def test_webcam_hdr_is_refused_naming_the_refresh_period(tmp_path: Path, capsys) -> None:
    """A 60 Hz webcam whose white screen needs one refresh period has no shorter bracket stop
    in whole periods: refused saying so and what to change, not as a camera whose exposure
    cannot be set."""
    argv = ["capture", str(tmp_path / "c"), "--emulate", "webcam", "--sim-size", "160x80"]
    assert main([*argv, "--yes", "--hdr"]) == 2
    err = capsys.readouterr().err
    assert "no HDR bracket fits in whole projector refresh periods" in err, err
    assert "ND filter" in err and "does not change its exposure" not in err
    assert not (tmp_path / "c").exists()
