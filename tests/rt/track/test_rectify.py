"""A view pointed at a face (rt/track/rectify.py): its pixels map back to the frame's along
the same rays (to a hundredth of a pixel, with and without lens distortion), its two ways of
resampling agree, and a face at the edge of a 90-degree webcam looks in it as one in the
middle does, where a plain enlarged crop shows it stretched."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest

from viewcomp.calib.world.eye import eye_from_angle
from viewcomp.rt.track.rectify import View
from viewcomp.rt.track.simscene import finish, render_person
from viewcomp.rt.track.simwalk import astronaut_person, walk_camera
from viewcomp.rt.track.yunet import YuNetDetector

BOX = np.array([80.0, 330.0, 40.0, 48.0])  # a face near the left edge, pixels
DOTS = np.array([[95.3, 345.2], [112.7, 346.1], [104.0, 365.5], [60.2, 300.9], [140.4, 410.6]])


def _dots(shape: tuple[int, int], at: np.ndarray, sigma: float = 1.5) -> np.ndarray:
    yy, xx = np.mgrid[0 : shape[0], 0 : shape[1]]
    img = sum(np.exp(-((xx - x) ** 2 + (yy - y) ** 2) / (2 * sigma**2)) for x, y in at)
    return np.clip(np.asarray(img) * 255, 0, 255).astype(np.uint8)


@pytest.mark.parametrize("distortion", [None, (-0.12, 0.03, 0.0, 0.0, 0.0)])
def test_a_view_maps_back_to_the_frame_exactly(distortion):
    """Dots drawn at known sub-pixel places near the frame's edge, found in the view by
    their centroids (where the view's rays say they are) and mapped back: within 0.06
    pixels (the blobs' own asymmetry after resampling)."""
    dev = replace(walk_camera(), distortion=distortion)
    view = View.of_box(dev, BOX, 160.0, 2.0)
    image = view.image(_dots((720, 1280), DOTS)).astype(np.float64)
    for p in DOTS:
        ray = dev.rays_through(p[None])[0]
        q = (view.axes[:2] @ ray) / (view.axes[2] @ ray) * view.focal + (view.size - 1) / 2
        x0, y0 = int(q[0]) - 15, int(q[1]) - 15
        w = image[y0 : y0 + 31, x0 : x0 + 31]
        gy, gx = np.mgrid[y0 : y0 + 31, x0 : x0 + 31]
        c = np.array([(w * gx).sum(), (w * gy).sum()]) / w.sum()
        np.testing.assert_allclose(c, q, atol=0.3)  # the dot is where the rays put it
        np.testing.assert_allclose(view.to_frame(c[None])[0], p, atol=0.06)


def test_a_plain_crop_maps_back_to_the_frame_exactly():
    """Without a camera the crop is a plain enlargement (4 times here): the dots' centroids
    in it map back within 0.06 pixels (pixel centres at integers in both, as cv2.resize
    takes them; dividing alone would be 0.375 pixels off)."""
    crop, to_frame = YuNetDetector()._crop(_dots((720, 1280), DOTS), BOX)
    image = crop.astype(np.float64)
    for p in DOTS[:3]:  # the ones inside the crop (2 box sizes each side of the centre)
        q = (p - BOX[:2] + 2.0 * BOX[3] - BOX[2:] / 2 + 0.5) * 4.0 - 0.5  # its place, coarsely
        x0, y0 = int(q[0]) - 15, int(q[1]) - 15
        w = image[y0 : y0 + 31, x0 : x0 + 31]
        gy, gx = np.mgrid[y0 : y0 + 31, x0 : x0 + 31]
        c = np.array([(w * gx).sum(), (w * gy).sum()]) / w.sum()
        np.testing.assert_allclose(to_frame(c[None])[0], p, atol=0.06)


def test_the_homography_and_the_rays_map_resample_alike():
    """A lens without distortion is warped by one homography; the same lens given as
    zero distortion goes through the rays' map on a grid: the two views of a textured frame
    differ by at most 2 grey levels (interpolation) away from the border."""
    rng = np.random.default_rng(0)
    frame = cv2.GaussianBlur(rng.integers(0, 256, (720, 1280), np.uint8), (0, 0), 2.0)
    pinhole = walk_camera()
    zero = replace(pinhole, distortion=(0.0, 0.0, 0.0, 0.0, 0.0))
    box = BOX + np.array([500.0, 0.0, 0.0, 0.0])  # nearer the middle
    a = View.of_box(pinhole, box, 160.0, 2.0).image(frame).astype(int)
    b = View.of_box(zero, box, 160.0, 2.0).image(frame).astype(int)
    assert a.shape == b.shape
    assert np.abs(a - b)[8:-8, 8:-8].max() <= 2


def _ncc(a: np.ndarray, b: np.ndarray) -> float:
    a, b = a.astype(np.float64) - a.mean(), b.astype(np.float64) - b.mean()
    return float((a * b).sum() / np.sqrt((a * a).sum() * (b * b).sum()))


def _head_box(dev, eye: np.ndarray) -> np.ndarray:
    """The pixel box of a head 0.16 m wide and 0.2 m tall (upright and square to the line
    of sight), centred where its middle (3 cm below the eyes) is imaged."""
    sight = eye - np.asarray(dev.position)
    sight /= np.linalg.norm(sight)
    side = np.cross(sight, [0.0, -1.0, 0.0])
    side /= np.linalg.norm(side)
    up = np.cross(side, sight)
    mid = eye - 0.03 * up
    corners = [mid + a * 0.08 * side + b * 0.1 * up for a in (-1, 1) for b in (-1, 1)]
    uv = dev.project(np.array(corners))
    size = uv.max(axis=0) - uv.min(axis=0)
    return np.concatenate([dev.project(mid[None])[0] - size / 2, size])  # centred on its middle


def test_a_face_at_the_edge_is_seen_as_in_the_middle():
    """The same head 2.5 m away straight ahead and 40 degrees aside (near the left edge of
    the 90-degree webcam, where it is imaged 1.3 times wider than tall): its views from
    both places match closely (normalised cross-correlation of the face's middle over 0.85);
    the plain enlarged crops (no camera model) do not, the edge one stretched."""
    dev = walk_camera()
    back = np.zeros((720, 1280, 3), np.float32)
    views, crops = [], []
    for angle in (90.0, 50.0):
        eye = eye_from_angle(angle, 2.5, 0.15)
        frame = finish(render_person(back, dev, astronaut_person(), eye), np.random.default_rng(0))
        box = _head_box(dev, eye)
        views.append(YuNetDetector(device=dev)._crop(frame, box)[0])
        crops.append(YuNetDetector()._crop(frame, box)[0])

    def middle(img: np.ndarray) -> np.ndarray:
        h, w = img.shape[:2]
        return img[h // 2 - 60 : h // 2 + 60, w // 2 - 60 : w // 2 + 60].mean(axis=2)

    seen = _ncc(middle(views[0]), middle(views[1]))
    plain = _ncc(middle(crops[0]), middle(crops[1]))
    assert seen > 0.85, (seen, plain)  # measured 0.90 (the drawn head's resampling)
    assert plain < seen - 0.3, (seen, plain)  # measured 0.17


def test_a_frame_of_another_size_than_the_camera_is_refused():
    dev = walk_camera()
    with pytest.raises(ValueError, match="a 640x360 frame for a tracking camera of 1280x720"):
        YuNetDetector(device=dev).refine(np.zeros((360, 640, 3), np.uint8), BOX)
