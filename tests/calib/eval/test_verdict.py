"""calibrate's verdict (calib/eval/verdict.py) and its report (calib/eval/calreport.py)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from viewcomp.calib.eval.calreport import REPORT_FILES, reachable_white
from viewcomp.calib.eval.verdict import judge
from viewcomp.calib.fit.calibrate import Calibration
from viewcomp.calib.io.imageio import read_rgb8
from viewcomp.calib.model.reference import screen_at, white_response


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "viewcomp", *args], capture_output=True, text=True, timeout=300
    )


@pytest.fixture(scope="module")
def bundles(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[Path, str]]:
    """The same glossy magenta screen calibrated from well- and under-exposed captures
    (0.15 of the default exposure), 160x80; each with its calibrate output and report."""
    root = tmp_path_factory.mktemp("verdict")
    out = {}
    for name, extra in (("dim", ["--exposure", "0.15"]), ("good", [])):
        caps, bundle = root / name, root / f"{name}.vcb"
        done = _cli("simulate", str(caps), "--screen", "magenta", "--gloss", "glossy",
                    "--size", "160x80", *extra)  # fmt: skip
        assert done.returncode == 0, done.stderr
        done = _cli("calibrate", str(caps), "-o", str(bundle), "--report", str(root / f"r-{name}"))
        assert done.returncode == 0, done.stderr
        out[name] = (bundle, done.stdout)
    return out


def test_underexposed_calibration_is_poor_with_its_reason(bundles) -> None:
    _, text = bundles["dim"]
    assert "verdict: POOR calibration" in text
    assert "- exposure " in text and "raise the camera's exposure" in text


def test_well_exposed_calibration_is_good(bundles) -> None:
    _, text = bundles["good"]
    assert "verdict: GOOD calibration" in text


def test_report_holds_the_verdict_and_the_pictures(bundles) -> None:
    for name, level in (("dim", "poor"), ("good", "good")):
        folder = bundles[name][0].parent / f"r-{name}"
        assert sorted(p.name for p in folder.iterdir()) == sorted(REPORT_FILES)
        data = json.loads((folder / "calibration.json").read_text())
        assert data["verdict"]["level"] == level
        assert {f["name"] for f in data["verdict"]["findings"]} >= {"exposure", "noise"}
        # the reach at 90 degrees: white | highest | lowest, each the grid's width
        w = Calibration.load(bundles[name][0]).shape[1]
        assert read_rgb8(folder / "reach.png").shape[1] == 3 * w + 2 * 4


def test_the_verdict_is_the_same_from_the_saved_bundle(bundles) -> None:
    cal = Calibration.load(bundles["dim"][0])
    assert judge(cal).level == "poor"
    old = Calibration(rig=cal.rig, paper=cal.paper, pixel=cal.pixel,
                      info={k: v for k, v in cal.info.items() if k != "quality"})  # fmt: skip
    # a bundle from before the quality was measured is judged on what it has
    assert {f.name for f in judge(old).findings}.isdisjoint({"exposure", "noise"})


def test_reachable_white_is_the_largest_feasible_white(bundles) -> None:
    """Checked against the definition, pixel by pixel: at k the drive solving M y + A = k t
    lies in [0, 1]^3; at k + 0.02 (where k < 1) it does not."""
    cal = Calibration.load(bundles["good"][0])
    eye = cal.eye(90.0)
    k = reachable_white(cal, eye)
    model = cal.pixel.runtime_model()
    h, w = model.shape
    t = white_response(model, np.full((h, w, 3), 255, np.uint8)).astype(np.float64)
    m, a = (np.asarray(x, np.float64) for x in screen_at(model, eye))
    rng = np.random.default_rng(0)
    for r, c in zip(rng.integers(0, h, 40), rng.integers(0, w, 40), strict=True):
        kk = float(k[r, c])
        y = np.linalg.solve(m[r, c], kk * t[r, c] - a[r, c])
        assert np.all(y >= -1e-6) and np.all(y <= 1 + 1e-6), (r, c, kk, y)
        if kk < 0.98:
            y2 = np.linalg.solve(m[r, c], (kk + 0.02) * t[r, c] - a[r, c])
            assert np.any(y2 < 0) or np.any(y2 > 1), (r, c, kk, y2)
    assert 0.1 < float(np.median(k)) < 0.9  # a magenta screen cannot show a full white
