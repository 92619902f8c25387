"""YuNet's search (rt/track/yunet.py): a small face the frame scores under the threshold is
looked at again in an enlarged crop, kept where the crop finds it, and an empty room stays
empty."""

from __future__ import annotations

import numpy as np
import pytest

from viewcomp.calib.world.eye import eye_from_angle
from viewcomp.rt.track.anatomy import head_pose
from viewcomp.rt.track.simscene import finish, render_person
from viewcomp.rt.track.simwalk import astronaut_person, background, walk_camera
from viewcomp.rt.track.yunet import YuNetConfig, YuNetDetector

HAND = (-0.9, 0.75, 0.9, 2.0)  # over mouth and chin (fractions of the face's size)


@pytest.mark.parametrize(("angle", "distance"), [(90.0, 2.5), (60.0, 3.0)])
def test_a_far_face_behind_a_hand_is_found_by_a_second_look(angle, distance):
    """A face 2.5-3 m away with mouth and chin covered: the frame's search scores it under
    0.6 (without the second look, ``candidate`` = ``score``, it is not found); the crop
    finds it, with the crop's landmarks (refined, not coarse), ranged within 10 %."""
    dev = walk_camera()
    eye = eye_from_angle(angle, distance, 0.15)
    frame = render_person(background(dev.resolution, 0), dev, astronaut_person(), eye,
                          occluder=HAND)  # fmt: skip
    frame = finish(frame, np.random.default_rng(0))
    assert len(YuNetDetector(YuNetConfig(candidate=0.6)).detect(frame)) == 0
    faces = YuNetDetector().detect(frame)
    assert len(faces) == 1 and faces.scores[0] >= 0.6 and not faces.coarse[0]
    got = head_pose(dev, faces.landmarks).range[0]
    truth = float(np.linalg.norm(eye - np.asarray(dev.position)))
    assert abs(got / truth - 1.0) < 0.1, got / truth


def test_empty_rooms_stay_empty():
    """Twenty empty rooms (the tracking tests' backgrounds): the search's low-scored boxes
    (some in every few frames) are not faces in the crop either."""
    dev = walk_camera()
    det = YuNetDetector()
    for seed in range(20):
        frame = finish(background(dev.resolution, 100 + seed), np.random.default_rng(seed))
        assert len(det.detect(frame)) == 0, seed


def test_the_second_look_is_bounded_by_the_threshold():
    with pytest.raises(ValueError, match="candidate must be in"):
        YuNetDetector(YuNetConfig(candidate=0.7))
    with pytest.raises(ValueError, match="candidate must be in"):
        YuNetDetector(YuNetConfig(candidate=0.0))
