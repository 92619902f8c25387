"""The per-pixel reach picture (calib/eval/reach_picture.py) against the simulator's truth,
and `preview --reach` on the command line."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np

from tests.support.calibrations import small_calibration, small_simulator
from viewcomp.calib.eval.reach_picture import reach_picture, reach_view
from viewcomp.calib.eval.testimages import natural_images
from viewcomp.calib.io.imageio import read_rgb8, write_png
from viewcomp.calib.sim.simulator import make_screen, white_screen


def test_reach_is_what_the_surface_shows_for_full_and_no_drive() -> None:
    """The highest colour is what the simulated eye sees of an all-white projection on the
    screen, the lowest of an all-black one, each relative to the white screen at full output:
    per pixel and channel from the picture's own 8-bit values, mean shares as printed."""
    cal = small_calibration(64, 32, screen="red")
    sim = small_simulator(64, 32)
    screen = make_screen("red", "glossy", shape=sim.shape, seed=0)
    eye = sim.rig.viewer.eye(60.0)
    full = np.full((32, 64, 3), 255, np.uint8)
    white = sim.observe_linear(white_screen(), full, eye).astype(np.float64)
    high = sim.observe_linear(screen, full, eye).astype(np.float64)
    low = sim.observe_linear(screen, np.zeros_like(full), eye).astype(np.float64)
    v = reach_view(cal, eye)
    resp = cal.rig.camera.response_curve()

    def lin(img: np.ndarray) -> np.ndarray:
        return np.asarray(resp.decode(img / 255.0), np.float64)

    usable = (v.white < 255).all(axis=-1) & (v.highest < 255).all(axis=-1)
    assert usable.mean() > 0.9
    got = lin(v.highest)[usable] / lin(v.white)[usable]
    want = high[usable] / white[usable]
    assert np.median(np.abs(got / want - 1.0)) < 0.05
    # red screen: its highest is red, it gives back much less green and blue than white
    assert np.median(want[:, 1]) < 0.6 * np.median(want[:, 0])
    assert np.median(got[:, 1]) < 0.6 * np.median(got[:, 0])
    assert abs(v.highest_share / (high.mean() / white.mean()) - 1.0) < 0.05
    assert abs(v.lowest_share / (low.mean() / white.mean()) - 1.0) < 0.1
    assert 0.0 < v.lowest_share < 0.1 < v.highest_share


def test_reach_picture_has_a_row_per_eye() -> None:
    cal = small_calibration(64, 32, screen="red")
    eyes = [(f"{a} deg", cal.eye(a)) for a in (60.0, 120.0)]
    one = reach_picture(cal, eyes[:1], "t")
    two = reach_picture(cal, eyes, "t")
    assert one.shape[1] == two.shape[1] == 3 * 64 + 2 * 4  # three columns, two gaps
    assert two.shape[0] > one.shape[0] + 32
    assert one.dtype == np.uint8


def test_cli_preview_writes_the_reach(tmp_path: Path) -> None:
    bundle = tmp_path / "screen.vcb"
    small_calibration(64, 32, screen="magenta").save(bundle)
    photo = tmp_path / "photo.png"
    write_png(photo, natural_images(64, 32)["coffee"])
    seen, reach = tmp_path / "seen.png", tmp_path / "reach.png"
    cmd = [sys.executable, "-m", "viewcomp", "preview", str(bundle), str(photo)]
    r = subprocess.run([*cmd, "-o", str(seen), "--angle", "60", "--reach", str(reach)],
                       capture_output=True, text=True, timeout=300)  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert f"wrote {reach}" in r.stdout
    assert read_rgb8(reach).shape[1] == 3 * 64 + 2 * 4
    for bad in (str(tmp_path / "reach.jpg"), str(seen)):
        r = subprocess.run([*cmd, "-o", str(seen), "--angle", "60", "--reach", bad],
                           capture_output=True, text=True, timeout=300)  # fmt: skip
        assert r.returncode == 2 and "--reach" in r.stderr and "Traceback" not in r.stderr
