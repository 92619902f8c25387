"""A live camera's faces (rt/track/live_faces.py): near faces at once from the half-resolution
search, far ones from the full search on the worker thread, then followed in crops."""

from __future__ import annotations

import numpy as np

from viewcomp.calib.world.eye import eye_from_angle
from viewcomp.rt.track.live_faces import LiveFaces
from viewcomp.rt.track.simscene import finish, render_person
from viewcomp.rt.track.simwalk import astronaut_person, background, walk_camera
from viewcomp.rt.track.yunet import YuNetDetector


def _frame(eyes: list[np.ndarray], seed: int = 0) -> np.ndarray:
    dev = walk_camera()
    f = background(dev.resolution, 0)
    for e in sorted(eyes, key=lambda e: -np.linalg.norm(e - np.asarray(dev.position))):
        f = render_person(f, dev, astronaut_person(), e)
    return finish(f, np.random.default_rng(seed))


def _alike(got: np.ndarray, want: np.ndarray) -> None:
    """Two estimates of a face's eyes (2, 2) pixels, from crops around different boxes: within
    2 pixels, and their separations (what ranges the face) within 3 %."""
    np.testing.assert_allclose(got, want, atol=2.0)
    ratio = np.linalg.norm(got[1] - got[0]) / np.linalg.norm(want[1] - want[0])
    assert abs(ratio - 1) < 0.03, ratio


def _wait(live: LiveFaces) -> None:
    assert live._pending is not None
    live._pending.result(timeout=60)


def test_near_at_once_far_after_the_full_search_then_followed():
    near, far = eye_from_angle(100, 1.4, 0.15), eye_from_angle(70, 3.2, 0.15)
    frames = [_frame([near, far], seed) for seed in range(3)]
    full = YuNetDetector().detect(frames[0])
    assert len(full) == 2  # the whole frame at full resolution sees both
    live = LiveFaces()
    try:
        first = live.detect(frames[0])
        assert len(first) == 1  # the near one, from the half-resolution search
        i = int(np.argmax(full.boxes[:, 2]))
        _alike(first.landmarks[0, :2], full.landmarks[i, :2])
        _wait(live)
        for frame in frames[1:]:  # the far one joins, then is followed in its crop
            got = live.detect(frame)
            assert len(got) == 2
            _wait(live)
        j = 1 - i
        far_got = got.landmarks[int(np.argmin(got.boxes[:, 2])), :2]
        _alike(far_got, full.landmarks[j, :2])
        assert live.full_searches >= 3
    finally:
        live.close()


def test_an_empty_frame_has_no_faces_and_close_ends_the_worker():
    live = LiveFaces()
    assert len(live.detect(_frame([]))) == 0
    live.close()
    assert live._pool._shutdown  # type: ignore[attr-defined]


def test_a_grey_frame_is_searched_as_a_colour_one():
    import cv2

    frame = _frame([eye_from_angle(95, 1.3, 0.15)])
    live = LiveFaces()
    try:
        grey = live.detect(cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY))
        colour = live.detect(frame)
        assert len(grey) == len(colour) == 1  # found; YuNet reads colour too, so not equal:
        g, c = grey.landmarks[0, :2], colour.landmarks[0, :2]
        np.testing.assert_allclose(g, c, atol=4.0)
        assert abs(np.linalg.norm(g[1] - g[0]) / np.linalg.norm(c[1] - c[0]) - 1) < 0.05
    finally:
        live.close()
