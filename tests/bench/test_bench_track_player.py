"""bench/bench_track_player.py's reading of a round: a newcomer's first eye is one its frame
found, timed from the frame the face entered (entry) and from the frame the eye came from
(appear); eyes the tracker publishes while nobody is found are not the newcomer's."""

from __future__ import annotations

import numpy as np
import pytest

from tests.support.scripts import load_script


def test_the_eased_eye_is_not_the_newcomers_and_entry_counts_from_the_faces_first_frame():
    bench = load_script("bench/bench_track_player.py")
    fps = bench.FPS
    capture = bench.SimulatedCapture([np.zeros((2, 2, 3), np.uint8)] * 60, fps, 4)
    capture.t0 = 0.0
    eased, face = np.array([0.1, 0.05, 0.6]), np.array([0.3, 0.15, 2.2])
    first, found_at = 10, 14  # the face enters at frame 10; its search finds it at frame 14
    published = [
        (first, 0.40, eased, False),  # the tracker easing home: nobody found in frame 10
        (found_at, 0.55, face, True),
        (found_at + 1, 0.58, face + 0.01, True),
    ]
    drawn = [(0.42, eased), (0.50, eased), (0.60, face), (0.62, face + 0.01)]
    got = bench.latencies(published, drawn, capture, [first], stay=30)
    assert got["entry_ms"] == [pytest.approx(1e3 * (0.60 - first / fps), abs=0.1)]
    assert got["appear_ms"] == [pytest.approx(1e3 * (0.60 - found_at / fps), abs=0.1)]
    assert got["first_eye_m"] == [pytest.approx(list(face))]
    assert got["all"]["n"] == 3  # every drawn eye, the eased one too
    # a face never found has no first eye, and is not counted as one
    none = bench.latencies(published[:1], drawn[:2], capture, [first], stay=30)
    assert none["entry_ms"] == [None] and none["entry"] == {"n": 0}


def test_accurate_is_timed_to_the_first_eye_within_the_tolerances():
    """A coarse first eye 25 % long, then one within 10 % and 10 cm: ``accurate`` is timed to
    the second, from the face's first frame; the first eye's distance ratio is 1.25."""
    bench = load_script("bench/bench_track_player.py")
    fps = bench.FPS
    capture = bench.SimulatedCapture([np.zeros((2, 2, 3), np.uint8)] * 60, fps, 4)
    capture.t0 = 0.0
    camera, truth = np.zeros(3), np.array([0.3, 0.15, 2.0])
    coarse, refined = 1.25 * truth, 1.02 * truth
    first = 10
    published = [(12, 0.45, coarse, True), (13, 0.50, refined, True)]
    drawn = [(0.47, coarse), (0.52, refined)]
    got = bench.latencies(published, drawn, capture, [first], 30, [truth], camera)
    assert got["first_eye_distance_ratio"] == [pytest.approx(1.25, abs=1e-3)]
    assert got["entry_ms"] == [pytest.approx(1e3 * (0.47 - first / fps), abs=0.1)]
    assert got["accurate_ms"] == [pytest.approx(1e3 * (0.52 - first / fps), abs=0.1)]
    # an eye right in distance but 15 cm aside is not accurate
    aside = refined + np.array([0.15, 0.0, 0.0])
    far = bench.latencies(published[:1], [(0.47, coarse), (0.52, aside)], capture, [first], 30,
                          [truth], camera)  # fmt: skip
    assert far["accurate_ms"] == [None] and far["accurate"] == {"n": 0}
