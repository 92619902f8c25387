"""Where the second look found no face (rt/track/refusals.py): looked at less and less often,
so a pattern of the room taken for a face costs a crop now and then, not every frame."""

from __future__ import annotations

import numpy as np
import pytest

from viewcomp.calib.world.eye import eye_from_angle
from viewcomp.rt.track.live_faces import LiveFaces
from viewcomp.rt.track.refusals import Refusals
from viewcomp.rt.track.simscene import finish, render_person
from viewcomp.rt.track.simwalk import astronaut_person, background, walk_camera
from viewcomp.rt.track.yunet import YuNetDetector

BOX = np.array([100.0, 50.0, 80.0, 96.0])


def aside(dx: float) -> np.ndarray:
    """:data:`BOX` moved ``dx`` pixels to the right."""
    return BOX + np.array([dx, 0.0, 0.0, 0.0])


def looks(refusals: Refusals, frames: int, box: np.ndarray = BOX) -> list[int]:
    """The frames on which a candidate offered at ``box`` on every frame, and refused every
    time it is looked at, is looked at."""
    out = []
    for t in range(frames):
        if t:
            refusals.tick()
        if refusals.due(box + t % 3):  # a box that jitters by a few pixels
            out.append(t)
            refusals.refused(box + t % 3)
    return out


def test_a_refused_place_is_remembered_without_being_offered():
    refusals = Refusals(max_wait=2, forget=3)
    assert not refusals.remembers(BOX)
    refusals.refused(BOX)
    assert refusals.remembers(aside(3.0)) and not refusals.remembers(aside(60.0))
    for _ in range(4):  # asked, not offered: forgotten as if nobody asked
        refusals.tick()
        refusals.remembers(BOX)
    assert not refusals.remembers(BOX)


def test_a_place_refused_again_and_again_waits_twice_as_long_each_time():
    assert looks(Refusals(), 140) == [0, 2, 5, 10, 19, 36, 69, 102, 135]
    assert looks(Refusals(max_wait=4, forget=8), 30) == [0, 2, 5, 10, 15, 20, 25]


def test_a_face_found_there_or_a_place_left_is_forgotten():
    r = Refusals(max_wait=8, forget=10)
    r.refused(BOX)
    assert not r.due(BOX) and r.due(aside(200.0))  # elsewhere: looked at
    r.found(BOX + 2)
    assert len(r) == 0 and r.due(BOX)
    r.refused(BOX)
    for _ in range(10):
        r.tick()
    assert len(r) == 1  # offered 10 frames ago: still remembered
    r.tick()
    assert len(r) == 0


def test_the_places_remembered_are_bounded():
    r = Refusals(capacity=3)
    for i in range(5):
        r.tick()
        r.refused(aside(100.0 * i))
    assert len(r) == 3
    assert r.due(BOX) and r.due(aside(100.0))  # the two offered first: dropped
    assert not r.due(aside(400.0))


def test_bad_settings_are_refused():
    with pytest.raises(ValueError, match="max_wait"):
        Refusals(max_wait=0)
    with pytest.raises(ValueError, match="forget >= max_wait"):
        Refusals(max_wait=8, forget=4)


def count_crops(monkeypatch: pytest.MonkeyPatch) -> list[bool]:
    """Each refinement crop YuNetDetector looks at from now on (not the quicker crops at the
    frame's own resolution): whether it found a face."""
    crops: list[bool] = []
    refine = YuNetDetector.refine

    def counted(self, frame, box, box_px=None, **kw):
        row = refine(self, frame, box, box_px, **kw)
        if box_px is None:
            crops.append(row is not None)
        return row

    monkeypatch.setattr(YuNetDetector, "refine", counted)
    return crops


def test_a_room_that_looks_like_a_face_costs_a_crop_now_and_then(monkeypatch):
    """An empty room (background seed 155) where the half-resolution search scores the same
    pattern as an unsure small face on every frame, and its crop refuses it: looked at on
    each of 24 frames without the refusals, on 5 with them (frames 0, 2, 5, 10, 19); the
    room stays empty."""
    dev = walk_camera()
    back = background(dev.resolution, 155)
    frames = [finish(back, np.random.default_rng((155, t))) for t in range(24)]
    crops = count_crops(monkeypatch)
    counted = []
    for remember in (False, True):
        live = LiveFaces(device=dev)
        if not remember:
            live.frame_detector.refusals = live.tile_detector.refusals = None
        crops.clear()
        assert sum(len(live.detect(f)) for f in frames) == 0
        assert not any(crops)
        counted.append(len(crops))
    assert counted[0] >= 22, counted  # the room does offer a candidate on (nearly) every frame
    assert counted[1] == 5, counted


def test_a_far_face_behind_a_hand_is_still_found_live():
    """Viewers 2.5-3 m away with mouth and chin covered walk into the room of the test
    above, its false candidate refused a few times already: each is found within one round
    of the tiles (4 frames) and in every frame after (the refusals hold the false place,
    not the room)."""
    dev = walk_camera()
    back = background(dev.resolution, 155)
    live = LiveFaces(device=dev)
    for t in range(12):  # the false candidate refused a few times already
        assert len(live.detect(finish(back, np.random.default_rng((155, t))))) == 0
    assert len(live.refusals) == 1
    person = astronaut_person()
    hand = (-0.9, 0.75, 0.9, 2.0)
    for angle, distance in ((60.0, 3.0), (110.0, 2.5)):
        eye = eye_from_angle(angle, distance, 0.15)
        face = render_person(back, dev, person, eye, occluder=hand)
        found = []
        for t in range(10):
            faces = live.detect(finish(face, np.random.default_rng((int(angle), t))))
            near = [np.hypot(*(b[:2] + b[2:] / 2 - dev.project(eye[None])[0])) < b[2]
                    for b in faces.boxes]  # fmt: skip
            found.append(any(near))
        first = found.index(True) if any(found) else None
        assert first is not None and first < 4, found
        assert all(found[first:]), found
        for _ in range(40):  # the viewer leaves: the tracker would forget them
            live.detect(finish(back, np.random.default_rng((int(angle), 99))))
