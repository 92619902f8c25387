"""The audience protocol: the zone's criteria on a reduced run, the walk's columns, the report."""

from __future__ import annotations

import json

import numpy as np
import pytest

from viewcomp.calib.eval.audience import walk_rows, zone_rows, zone_summary
from viewcomp.calib.eval.evaluate import World
from viewcomp.calib.eval.testimages import natural_images


@pytest.mark.slow
def test_reduced_zone_audience_beats_90_and_the_centre():
    """Viewers over 60..120 and over 30..90 on two glossy screens: the audience
    compensation's zone mean below both the 90-degree and the zone-centre compensation's,
    its worst viewer below the 90-degree compensation's, the oracle below all."""
    world = World.make(seed=1, size=(320, 160))
    imgs = dict(list(natural_images(320, 160).items())[1:2])
    rows = zone_rows(world, zones=((60, 120), (30, 90)), screens=("green", "magenta"),
                     images=imgs, judge=7)  # fmt: skip
    summary = zone_summary(rows)
    for name, z in summary.items():
        assert z["audience_mean_lt_90_and_centre"], (name, z)
        assert z["audience_worst_lt_90"], (name, z)
        assert z["mean"]["oracle"] < z["mean"]["pixel_audience"], (name, z)
    assert summary["60:120"]["mean"]["pixel_centre"] == summary["60:120"]["mean"]["pixel_90"]
    assert summary["30:90"]["mean"]["pixel_centre"] != summary["30:90"]["mean"]["pixel_90"]


def _walk(n: int = 12) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(n) / 30.0
    theta = np.radians(np.linspace(60.0, 120.0, n))
    return t, np.stack([2.0 * np.cos(theta), np.full(n, 0.15), 2.0 * np.sin(theta)], axis=-1)


def test_walk_with_a_perfect_tracker_is_the_exact_eye():
    world = World.make(seed=0, size=(96, 48))
    t, truth = _walk()
    out = walk_rows(world, t, truth, truth.copy(), delay=0, every=4)
    assert out["summary"]["frames_judged"] == 3
    for r in out["rows"]:
        assert r["de"]["tracked"] == r["de"]["exact"]
        assert r["eye_error_m"] == 0.0
    assert out["scale"] == pytest.approx(0.5 / np.hypot(2.0, 0.15))
    json.dumps(out)  # JSON-safe


def test_walk_with_a_wrong_eye_is_worse_than_the_exact_eye():
    """Tracked 40 degrees off: what the viewer sees is further from the white screen's."""
    world = World.make(seed=0, size=(96, 48))
    t, truth = _walk()
    theta = np.arctan2(truth[:, 2], truth[:, 0]) + np.radians(40.0)
    off = np.stack([2.0 * np.cos(theta), truth[:, 1], 2.0 * np.sin(theta)], axis=-1)
    out = walk_rows(world, t, truth, off, delay=0, every=3)
    s = out["summary"]["mean"]
    assert s["tracked"] > s["exact"] + 0.1, s


def test_run_writes_the_audience_report(tmp_path):
    """The protocol end to end on one small screen, with a walk: report.json and report.md
    hold the zones' table and the walk's."""
    from viewcomp.calib.eval.run import run

    t, truth = _walk(8)
    rep = run(tmp_path / "r", "audience", size=(48, 24), screens=("magenta",),
              walk=(t, truth, truth.copy()))  # fmt: skip
    saved = json.loads((tmp_path / "r" / "report.json").read_text())
    assert set(saved["zone_summary"]) == {"60:120", "30:90"}
    assert saved["walk"]["summary"]["frames_judged"] == 2 == rep["walk"]["summary"]["frames_judged"]
    md = (tmp_path / "r" / "report.md").read_text()
    assert "| 60:120 | mean |" in md and "Tracked walk" in md
