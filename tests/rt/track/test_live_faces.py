"""A live camera's faces (rt/track/live_faces.py): near faces at once from the half-resolution
search, far ones from the full-resolution tiles within a round of them, then followed in
crops."""

from __future__ import annotations

import numpy as np
import pytest

from viewcomp.calib.world.eye import eye_from_angle
from viewcomp.rt.track.live_faces import (
    OVERLAP,
    SCALE,
    TILES,
    TRACKING_EVERY,
    LiveFaces,
    tiles,
)
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


NEAR, FAR = eye_from_angle(100, 1.4, 0.15), eye_from_angle(70, 3.2, 0.15)


@pytest.mark.parametrize("angle", [65.0, 115.0])  # the frame's left and right halves
def test_a_far_newcomer_to_an_empty_room_is_found_within_a_round_of_tiles(angle):
    n = TILES[0] * TILES[1]
    far = eye_from_angle(angle, 3.2, 0.15)
    frames = [_frame([far], seed) for seed in range(n)]
    full = YuNetDetector().detect(frames[0])
    assert len(full) == 1  # the whole frame at full resolution sees it,
    assert len(YuNetDetector().detect(frames[0], SCALE)) == 0  # the half-resolution one not
    live = LiveFaces()
    got = [live.detect(f) for f in frames]
    counts = [len(g) for g in got]
    assert counts[-1] == 1, counts
    k = counts.index(1)  # found by its tile as the whole frame at full resolution finds it
    _alike(got[k].landmarks[0, :2], YuNetDetector().detect(frames[k]).landmarks[0, :2])
    assert len(live.detect(_frame([far], n))) == 1  # and followed from then on


def test_near_at_once_far_within_a_round_of_tiles_while_tracking_then_followed():
    rounds = TILES[0] * TILES[1] * TRACKING_EVERY
    frames = [_frame([NEAR, FAR], seed) for seed in range(rounds + 2)]
    full = YuNetDetector().detect(frames[0])
    assert len(full) == 2
    i = int(np.argmax(full.boxes[:, 2]))
    live = LiveFaces()
    got = [live.detect(f) for f in frames]
    _alike(got[0].landmarks[0, :2], full.landmarks[i, :2])  # the near one, at once
    counts = [len(g) for g in got]
    assert counts[rounds - 1] == 2, counts  # the far one by the end of a round of tiles,
    assert counts == sorted(counts), counts  # and not lost after: followed in its crop
    last = got[-1]
    _alike(last.landmarks[int(np.argmin(last.boxes[:, 2])), :2], full.landmarks[1 - i, :2])


def test_the_tiles_cover_the_frame_each_face_whole_in_one():
    w, h = 1280, 720
    grid = tiles(w, h, *TILES, OVERLAP)
    assert len(grid) == TILES[0] * TILES[1] and len({g[2:] for g in grid}) == 1  # one size
    cover = np.zeros((h, w), int)
    for x0, y0, tw, th in grid:
        assert 0 <= x0 and x0 + tw <= w and 0 <= y0 and y0 + th <= h
        cover[y0 : y0 + th, x0 : x0 + tw] += 1
    assert cover.min() >= 1
    rng = np.random.default_rng(0)
    for _ in range(500):  # any box up to OVERLAP wide lies wholly inside some tile
        s = rng.uniform(8, OVERLAP)
        x, y = rng.uniform(0, w - s), rng.uniform(0, h - s)
        assert any(
            x0 <= x and x + s <= x0 + tw and y0 <= y and y + s <= y0 + th for x0, y0, tw, th in grid
        )
    assert tiles(100, 50, 2, 2, 96) == [(0, 0, 100, 50)] * 4  # a small frame: itself


def test_an_empty_frame_has_no_faces_and_searches_a_tile_each_frame():
    live = LiveFaces()
    for k in range(3):
        assert len(live.detect(_frame([], seed=k))) == 0
    assert live.tiles_searched == 3


def test_a_grey_frame_is_searched_as_a_colour_one():
    import cv2

    frame = _frame([eye_from_angle(95, 1.3, 0.15)])
    live = LiveFaces()
    grey = live.detect(cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY))
    colour = live.detect(frame)
    assert len(grey) == len(colour) == 1  # found; YuNet reads colour too, so not equal:
    g, c = grey.landmarks[0, :2], colour.landmarks[0, :2]
    np.testing.assert_allclose(g, c, atol=4.0)
    assert abs(np.linalg.norm(g[1] - g[0]) / np.linalg.norm(c[1] - c[0]) - 1) < 0.05
