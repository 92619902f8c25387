"""Several viewers over time: identities kept through crossing, entering and leaving
(:class:`viewcomp.rt.track.tracker.EyeTracker`, Hungarian assignment to predicted eyes)."""

from __future__ import annotations

import numpy as np

from viewcomp.rt.track.tracker import EyeTracker, TrackerConfig


def _ids_by_truth(tracker: EyeTracker, truth: np.ndarray, t: float) -> list[int]:
    """The id of the track seen at t nearest to each true eye."""
    seen = [tr for tr in tracker.tracks if tr.seen == t]
    return [min(seen, key=lambda tr: float(np.linalg.norm(tr.eye - e))).id for e in truth]


def test_two_viewers_crossing_keep_their_identities():
    """Two viewers walk past each other (1 m/s each way, 0.3 m apart in depth, centimetre
    noise): each keeps its track id, and only two tracks ever exist."""
    rng = np.random.default_rng(0)
    tracker = EyeTracker(TrackerConfig(faces="all", gate=0.5))
    first = None
    for i in range(60):
        t = i / 30.0
        x = -1.0 + t
        truth = np.array([[x, 0.15, 2.0], [-x, 0.15, 2.3]])
        eyes = truth + rng.normal(0.0, 0.01, truth.shape)
        order = rng.permutation(2)  # the detector lists faces in any order
        tracker.update(eyes[order], np.zeros((2, 4)), t)
        ids = _ids_by_truth(tracker, truth, t)
        first = ids if first is None else first
        assert ids == first, f"frame {i}: identities swapped"
    assert {tr.id for tr in tracker.tracks} == set(first)


def test_a_viewer_entering_and_one_leaving():
    """A third viewer enters at frame 10 and gets a new id; one leaves at frame 20 and its
    track ends after ``hold``; the others keep theirs."""
    tracker = EyeTracker(TrackerConfig(faces="all", hold=0.3))
    a, b, c = np.array([-0.5, 0.1, 2.0]), np.array([0.6, 0.2, 2.5]), np.array([0.0, 0.1, 1.5])
    out = None
    for i in range(40):
        t = i / 30.0
        eyes = [a, b] if i < 20 else [a]
        if i >= 10:
            eyes = [*eyes, c]
        out = tracker.update(np.asarray(eyes), np.zeros((len(eyes), 4)), t)
        if i == 15:
            assert len(tracker.tracks) == 3 and len(out) == 3
    assert out is not None and len(out) == 2  # b ended 0.3 s after it was last seen
    assert sorted(tr.id for tr in tracker.tracks) == [0, 2]
    np.testing.assert_allclose(out[0], c, atol=1e-9)  # nearest first


def test_a_far_jump_is_a_new_viewer():
    """An eye farther than the gate from every predicted eye starts a new track."""
    tracker = EyeTracker(TrackerConfig(faces="all", gate=0.5))
    tracker.update(np.array([[0.0, 0.1, 2.0]]), np.zeros((1, 4)), 0.0)
    tracker.update(np.array([[1.5, 0.1, 2.0]]), np.zeros((1, 4)), 1 / 30)
    assert sorted(tr.id for tr in tracker.tracks) == [0, 1]


def test_a_coarse_first_reading_gives_way_to_the_first_refined_one():
    """A newcomer's first reading is coarse (the search's own landmarks): the tracker
    publishes it at once, then starts afresh at the first refined reading of the same face
    (its box overlapping), even 0.65 m away along the line of sight, beyond the 0.5 m gate:
    one track, whose eye is the refined reading itself, with no velocity from the jump. The
    same two readings both refined are two viewers (the gate)."""
    coarse_eye, refined_eye = np.array([0.3, 0.15, 2.6]), np.array([0.25, 0.15, 1.95])
    box, moved = np.array([[600.0, 300.0, 40.0, 48.0]]), np.array([[602.0, 301.0, 41.0, 48.0]])
    tracker = EyeTracker(TrackerConfig(faces="all", gate=0.5))
    first = tracker.update(coarse_eye[None], box, 0.0, coarse=np.array([True]))
    np.testing.assert_array_equal(first, coarse_eye[None])
    (tr,) = tracker.tracks
    assert tr.provisional
    out = tracker.update(refined_eye[None], moved, 0.1, coarse=np.array([False]))
    (tr,) = tracker.tracks
    np.testing.assert_array_equal(out, refined_eye[None])
    assert not tr.provisional and not np.any(tr.velocity)
    # later readings are smoothed as usual: a refined track is not restarted by a coarse one
    tracker.update((refined_eye + 0.05)[None], moved, 0.2, coarse=np.array([True]))
    assert not tr.provisional and tr.eye[0] < refined_eye[0] + 0.05

    both = EyeTracker(TrackerConfig(faces="all", gate=0.5))
    both.update(coarse_eye[None], box, 0.0)
    both.update(refined_eye[None], moved, 0.1)
    assert len(both.tracks) == 2


def test_a_coarse_reading_elsewhere_in_the_picture_is_another_viewer():
    """The box overlap that lets a provisional track jump its gate is the picture's: a
    refined face far from its box is matched by the 3-D gate alone."""
    tracker = EyeTracker(TrackerConfig(faces="all", gate=0.5))
    tracker.update(np.array([[0.3, 0.15, 2.6]]), np.array([[600.0, 300, 40, 48]]), 0.0,
                   coarse=np.array([True]))  # fmt: skip
    tracker.update(np.array([[-0.8, 0.15, 1.9]]), np.array([[200.0, 300, 60, 70]]), 0.1,
                   coarse=np.array([False]))  # fmt: skip
    assert len(tracker.tracks) == 2 and tracker.tracks[0].provisional


def test_coarse_flags_must_match_the_eyes():
    import pytest

    with pytest.raises(ValueError, match="coarse has 2 faces, eyes 1"):
        EyeTracker().update(np.ones((1, 3)), np.zeros((1, 4)), 0.0, coarse=np.zeros(2, bool))


def test_a_coarse_newcomer_does_not_take_over_from_the_followed_viewer():
    """With ``faces="nearest"`` following a viewer 2 m away, a newcomer's coarse first
    reading puts them at 1.5 m (really 2.1 m): the published eye stays the followed viewer's,
    and the refined reading, farther, does not take over either. With nobody followed, a
    coarse newcomer is published at once."""
    tracker = EyeTracker(TrackerConfig(faces="nearest", switch_margin=0.3))
    viewer = np.array([-0.5, 0.15, 2.0])
    box_v, box_n = np.array([300.0, 300, 40, 48]), np.array([800.0, 300, 40, 48])
    for i in range(3):
        tracker.update(viewer[None], box_v[None], i / 10)
    coarse, refined = np.array([0.5, 0.15, 1.5]), np.array([0.5, 0.15, 2.1])
    out = tracker.update(np.array([viewer, coarse]), np.array([box_v, box_n]), 0.3,
                         coarse=np.array([False, True]))  # fmt: skip
    np.testing.assert_allclose(out[0], viewer)
    out = tracker.update(np.array([viewer, refined]), np.array([box_v, box_n]), 0.4,
                         coarse=np.array([False, False]))  # fmt: skip
    np.testing.assert_allclose(out[0], viewer)

    alone = EyeTracker(TrackerConfig(faces="nearest"))
    out = alone.update(coarse[None], box_n[None], 0.0, coarse=np.array([True]))
    np.testing.assert_array_equal(out[0], coarse)
