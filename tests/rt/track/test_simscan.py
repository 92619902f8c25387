"""The scanned head's renderer (viewcomp.rt.track.simscan): a textured mesh read from a
Wavefront OBJ file, put in the head's frame by its landmarks, drawn texel by texel."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from viewcomp.rt.track.simscan import Scan, read_obj, render_scan
from viewcomp.rt.track.simwalk import walk_camera

# a card 120 x 140 mm, 0.5 mm a texel, the eyes 64 mm apart 20 mm below its top edge
EYES_MM = np.array([[-32.0, 40.0, 0.0], [32.0, 40.0, 0.0]])
MOUTH_MM = np.array([[-25.0, -30.0, 0.0], [25.0, -30.0, 0.0]])
NOSE_MM = np.array([0.0, 5.0, 30.0])


def card_obj(tmp_path, clockwise: bool = False):
    """An OBJ file of the card (two triangles, out of the face toward +z unless
    ``clockwise``) and its texture: light grey, a dark dot 6 mm square on each eye."""
    tex = np.full((280, 240, 3), 230, np.uint8)
    for x, y, _ in EYES_MM:  # texel of (x, y) mm: u = (x + 60) / 120, v up = (y + 80) / 140
        cx, cy = int((x + 60) * 2), int((140 - (y + 80)) * 2)  # texel centres at x, y: - 0.5
        tex[cy - 6 : cy + 6, cx - 6 : cx + 6] = 20  # texels cx - 6 .. cx + 5: centred on x
    corners = [(-60, -80), (60, -80), (60, 60), (-60, 60)]
    lines = [f"v {x} {y} 0" for x, y in corners]
    lines += [f"vt {(x + 60) / 120} {(y + 80) / 140}" for x, y in corners]
    tris = [(1, 2, 3), (1, 3, 4)]
    if clockwise:
        tris = [t[::-1] for t in tris]
    lines += ["f " + " ".join(f"{i}/{i}" for i in t) for t in tris]
    path = tmp_path / "card.obj"
    path.write_text("# a card\n" + "\n".join(lines) + "\n")
    return path, tex


def card(tmp_path, clockwise: bool = False) -> Scan:
    path, tex = card_obj(tmp_path, clockwise)
    v, f, uv = read_obj(path)
    return Scan.annotated("card", v, f, uv, tex, EYES_MM, MOUTH_MM, NOSE_MM)


def dark_dots(frame: np.ndarray, light: float = 0.9) -> np.ndarray:
    """(k, 2) pixels, left to right: the darkness-weighted centroids of the blobs darker
    than the card (``light``, 230 / 255 too) by more than 0.1."""
    dark = np.clip(min(light, 230 / 255) - frame.mean(axis=2), 0.0, None)
    n, labels = cv2.connectedComponents((dark > 0.1).astype(np.uint8))
    yy, xx = np.mgrid[: frame.shape[0], : frame.shape[1]]
    pts = []
    for i in range(1, n):
        grow = cv2.dilate((labels == i).astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
        w = dark * grow
        pts.append([(w * xx).sum() / w.sum(), (w * yy).sum() / w.sum()])
    out = np.asarray(pts).reshape(-1, 2)
    return out[np.argsort(out[:, 0])]


def test_the_head_frame_comes_from_the_landmarks(tmp_path):
    """Eyes one unit apart on the lateral axis, the mouth's midpoint straight below them in
    their plane, the nose forward: the card's own axes, scaled by 1 / 64 mm."""
    s = card(tmp_path)
    assert s.nose == pytest.approx([0.0, -35.0 / 64, 30.0 / 64])
    mid = EYES_MM.mean(axis=0)
    assert s.vertices[0] == pytest.approx((np.array([-60.0, -80.0, 0.0]) - mid) / 64.0)
    assert s.spacing() == pytest.approx(0.5 / 64, rel=1e-9)


def test_a_head_wound_the_other_way_is_drawn_the_same(tmp_path):
    dev = walk_camera()
    back = np.full((720, 1280, 3), 0.5, np.float32)
    eye = np.array([0.1, 0.2, 1.2])
    a = render_scan(back, dev, card(tmp_path), eye, math.radians(20))
    (tmp_path / "cw").mkdir()
    b = render_scan(back, dev, card(tmp_path / "cw", True), eye, math.radians(20))
    assert np.array_equal(a, b)
    assert (a != back).any()


@pytest.mark.parametrize(("distance", "turn_deg"), [(0.8, 0), (1.5, 35), (1.5, -50), (3.4, 25)])
def test_the_eyes_are_drawn_where_landmarks_says(tmp_path, distance, turn_deg):
    """The texels of the dots on the eyes land, seen by the camera, within 0.6 pixels of the
    eyes :meth:`Scan.landmarks` projects (the card lies in the eyes' plane), at every
    distance (texture level) and turn: each texel is drawn at its nearest pixel (measured
    up to 0.51 off)."""
    dev = walk_camera()
    s = card(tmp_path)
    back = np.full((720, 1280, 3), 0.9, np.float32)
    eye = np.array([0.2, 0.15, distance])
    turn = math.radians(turn_deg)
    frame = render_scan(back, dev, s, eye, turn)
    want = dev.project(s.landmarks(dev, eye, turn))[:2]
    dots = dark_dots(frame)
    assert len(dots) == 2, dots
    assert np.abs(dots - want).max() < 0.6, (dots, want)


@pytest.mark.parametrize("level", range(5))
def test_every_texture_level_puts_its_texels_where_the_texture_is(tmp_path, level):
    """The darkness-weighted mean of a level's texels on the surface is the dot's centre
    within 0.2 mm (the levels' pixel centres line up with the finer ones': off by
    2^(level-1) - 0.5 texels, level 3 put them 1.75 mm aside)."""
    s = card(tmp_path)
    pts, normals, colour = s.texels(level)
    assert normals == pytest.approx(np.tile([0.0, 0.0, 1.0], (len(pts), 1)))
    dark = np.clip(230 / 255 - colour.mean(axis=1), 0.0, None)
    for side in (-1, 1):
        w = dark * (np.sign(pts[:, 0]) == side)
        centre = (w[:, None] * pts).sum(axis=0) / w.sum()
        assert np.abs(centre - [0.5 * side, 0.0, 0.0]).max() * 64.0 < 0.2, (side, centre)


def test_a_head_turned_away_is_not_drawn(tmp_path):
    """The card turned 120 degrees shows the camera its back: nothing is drawn."""
    dev = walk_camera()
    back = np.full((720, 1280, 3), 0.5, np.float32)
    frame = render_scan(back, dev, card(tmp_path), np.array([0.0, 0.15, 1.5]), math.radians(120))
    assert np.array_equal(frame, back)


def test_the_occluder_covers_the_face_below_the_eyes(tmp_path):
    """An occluder from 0.75 to 2 eye separations below the eyes: drawn dark grey over the
    card's mouth, not over its eyes."""
    dev = walk_camera()
    back = np.full((720, 1280, 3), 0.9, np.float32)
    eye = np.array([0.0, 0.15, 1.0])
    s = card(tmp_path)
    frame = render_scan(back, dev, s, eye, occluder=(-0.9, 0.75, 0.9, 2.0))
    below = eye - np.array([0.0, 1.1 * 0.063, 0.0])  # about 1.1 separations below, on the card
    u, v = np.rint(dev.project(below[None])[0]).astype(int)
    assert frame[v, u] == pytest.approx([0.18] * 3, abs=1e-6)
    assert len(dark_dots(frame)) >= 1  # the eyes stay drawn above it


@pytest.mark.parametrize(
    ("text", "why"),
    [
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nf 1/1 2/1 3/1 4/1\n", "not a triangle"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "not a triangle with texture"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 9/1\n", "not given"),
        ("v 0 0 x\n", ":1:"),
        ("# nothing\n", "no textured triangles"),
    ],
)
def test_a_bad_mesh_file_is_refused_with_its_name(tmp_path, text, why):
    path = tmp_path / "bad.obj"
    path.write_text(text)
    with pytest.raises(ValueError, match=r"bad\.obj") as err:
        read_obj(path)
    assert why in str(err.value)


def test_a_mesh_file_too_large_is_refused_before_it_is_read(tmp_path, monkeypatch):
    import viewcomp.rt.track.simscan as simscan

    path, _ = card_obj(tmp_path)
    monkeypatch.setattr(simscan, "MAX_BYTES", path.stat().st_size - 1)
    with pytest.raises(ValueError, match="bytes, more than"):
        read_obj(path)


def test_the_scanned_heads_eyes_are_where_a_detector_finds_them():
    """menpo3d's scan (tests/support/people.py) drawn facing the camera at 0.8-3 m, straight
    ahead and 0.4 m aside: YuNet's eyes lie within 0.15 of the eye separation of the eye
    centres its annotation gives (measured at most 0.105), its nose within 0.25 of the nose
    tip's (at most 0.18): the annotation is read as the scan's authors placed it and the
    head is drawn in its frame."""
    from tests.support.people import scanned
    from viewcomp.rt.track.simscene import finish
    from viewcomp.rt.track.simwalk import background
    from viewcomp.rt.track.yunet import YuNetDetector

    s = scanned()
    dev = walk_camera()
    back = background(dev.resolution, 0)
    det = YuNetDetector(device=dev)
    rng = np.random.default_rng(1)
    for d in (0.8, 1.2, 1.6, 2.0, 2.5, 3.0):
        for x in (-0.4, 0.0, 0.4):
            eye = np.array([x, 0.15, d])
            faces = det.detect(finish(s.render(back, dev, eye), rng))
            want = dev.project(s.landmarks(dev, eye))
            sep = np.linalg.norm(want[1] - want[0])
            assert len(faces) == 1, (d, x)
            err = np.linalg.norm(faces.landmarks[0][:3] - want, axis=1) / sep
            assert err[0] < 0.15 and err[1] < 0.15 and err[2] < 0.25, (d, x, err)
