"""A face's noise and the smoothing of its refinement crop (rt/track/noise.py), and the bias
it takes back: a noisy face ranged short (rt/track/yunet.py's crops)."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from viewcomp.calib.world.eye import eye_from_angle
from viewcomp.rt.track import yunet
from viewcomp.rt.track.anatomy import head_pose
from viewcomp.rt.track.noise import MAX_SIGMA, QUIET, noise_sigma, relative_noise, smoothing
from viewcomp.rt.track.simscene import finish, render_person, through_webcam
from viewcomp.rt.track.simwalk import astronaut_person, background, walk_camera
from viewcomp.rt.track.yunet import YuNetDetector


def _shaded(h: int = 120, w: int = 160) -> np.ndarray:
    """A smooth picture: a plane of grey levels plus a gentle curve (no noise)."""
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    return 60.0 + 0.5 * x + 0.3 * y + 10.0 * np.sin(x / 40.0) * np.cos(y / 50.0)


@pytest.mark.parametrize("sigma", [1.0, 3.0, 8.0])
def test_the_noise_of_a_smooth_picture_is_recovered(sigma):
    rng = np.random.default_rng(1)
    grey = _shaded() + rng.normal(0.0, sigma, (120, 160))
    assert noise_sigma(grey) == pytest.approx(sigma, rel=0.06)


def test_a_plane_and_gentle_shading_read_as_no_noise():
    assert noise_sigma(_shaded()) < 0.1


def test_relative_noise_is_the_noise_over_the_faces_contrast():
    """Grey BGR (the channels alike, so the grey noise is theirs): a box holding grey levels
    spread evenly over 100 (5th to 95th percentile: 90) in a frame with noise 3."""
    rng = np.random.default_rng(2)
    frame = np.full((200, 200), 120.0)
    frame[80:120, 80:120] = np.linspace(70.0, 170.0, 40)[None, :]
    noisy = np.clip(frame + rng.normal(0.0, 3.0, frame.shape), 0, 255).round().astype(np.uint8)
    bgr = np.repeat(noisy[:, :, None], 3, axis=2)
    rho = relative_noise(bgr, np.array([80.0, 80.0, 40.0, 40.0]))
    assert rho == pytest.approx(3.0 / 90.0, rel=0.12)
    assert relative_noise(noisy, np.array([80.0, 80.0, 40.0, 40.0])) == rho  # grey alike
    assert relative_noise(np.full((50, 50, 3), 90, np.uint8), np.array([10.0, 10, 20, 20])) == 0


def test_smoothing_starts_past_quiet_and_averages_the_noise_down_to_it():
    assert smoothing(0.0) == 0.0 and smoothing(QUIET) == 0.0
    s = smoothing(3.0 * QUIET)
    assert s == pytest.approx(3.0 / (2.0 * math.sqrt(math.pi)))
    # measured: white noise under a Gaussian of that width comes down by about 3
    rng = np.random.default_rng(3)
    noise = rng.normal(0.0, 1.0, (400, 400)).astype(np.float32)
    smoothed = cv2.GaussianBlur(noise, (0, 0), s)
    assert np.std(smoothed) == pytest.approx(1.0 / 3.0, rel=0.15)
    assert smoothing(1.0) == MAX_SIGMA
    assert smoothing(2.0 * QUIET) < smoothing(2.5 * QUIET)


POSES = [(70, 2.6), (80, 3.3), (90, 2.9), (100, 3.4), (110, 2.7), (75, 3.0), (95, 3.2), (105, 2.5)]


def _ratios(noise: float) -> list[float]:
    """Distance ratios (measured / true) of the astronaut at POSES, facing the camera in a
    frame with ``noise`` (share of full scale, each channel), one frame each."""
    dev = walk_camera()
    back = background(dev.resolution, 3)
    det = YuNetDetector(device=dev)
    person = astronaut_person()
    rng = np.random.default_rng(4)
    out = []
    for angle, distance in POSES:
        eye = eye_from_angle(angle, distance, 0.1)
        faces = det.detect(finish(render_person(back, dev, person, eye), rng, noise))
        assert len(faces) == 1
        got = head_pose(dev, faces.landmarks[:1]).eyes[0]
        p = np.asarray(dev.position)
        out.append(float(np.linalg.norm(got - p) / np.linalg.norm(eye - p)))
    return out


def test_a_noisy_far_face_is_ranged_short_unless_its_crop_is_smoothed(monkeypatch):
    """Poses of this test's own (2.5-3.4 m), 6 % noise in each channel (a webcam's gain in a
    dim room): YuNet's eyes in the unsmoothed crop read wide, the faces ranged short; the
    crop smoothed by its noise ranges them within a few per cent."""
    smoothed = np.median(_ratios(0.06))
    monkeypatch.setattr(yunet, "smoothing", lambda rho: 0.0)
    raw = np.median(_ratios(0.06))
    assert raw < 0.95, raw  # the bias this is about
    assert abs(smoothed - 1.0) < 0.03 and abs(smoothed - 1.0) < 0.5 * abs(raw - 1.0), smoothed


def test_ordinary_frames_are_not_smoothed():
    """A face with 1 % noise (the people test's frames) and one through the emulated webcam
    (its denoising) are under QUIET: their crops are left as they are, so a turned head's
    nose moves as it did."""
    dev = walk_camera()
    back = background(dev.resolution, 3)
    det = YuNetDetector(device=dev)
    rng = np.random.default_rng(5)
    face = render_person(back, dev, astronaut_person(), eye_from_angle(85, 3.0, 0.1))
    for frame in (finish(face, rng, 0.01), through_webcam(face, rng)):
        box = det.detect(frame).boxes[0]
        assert relative_noise(frame, box) < QUIET
