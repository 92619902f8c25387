"""The tracking tests' emulated webcam (rt/track/simscene.py ``through_webcam``): the
calibration emulator's webcam sensor and processing applied to a frame an ideal camera would
deliver."""

from __future__ import annotations

import numpy as np

from viewcomp.calib.emu.camera import tone_curve
from viewcomp.calib.emu.profiles import WEBCAM
from viewcomp.calib.world.response import parse_response
from viewcomp.rt.track.simscene import through_webcam


def test_a_grey_field_comes_back_through_the_webcams_tone_curve_with_its_noise():
    """A flat sRGB grey of 0.3 becomes the webcam's tone curve of the same light (its
    S-curve on top of sRGB: 71 where an ideal camera gives 76.5), within 1.5 code values on
    average, with the sensor's noise (smoothed by its denoising) and no colour cast."""
    frame = np.full((96, 128, 3), 0.3, np.float32)
    out = through_webcam(frame, np.random.default_rng(0)).astype(np.float64)
    assert out.shape == (96, 128, 3)
    light = parse_response("srgb").decode(np.array([0.3]))
    want = 255.0 * tone_curve(light, WEBCAM.tone_s)[0]
    inner = out[8:-8, 8:-8]
    np.testing.assert_allclose(inner.mean(axis=(0, 1)), want, atol=1.5)
    assert 0.2 < inner.std() < 4.0


def test_edges_are_softened_as_a_webcams_are():
    """A sharp vertical edge spreads over several pixels (optics, demosaicing, denoising;
    sharpening overshoots a little): the ideal camera's one-pixel step is gone."""
    frame = np.zeros((64, 64, 3), np.float32)
    frame[:, 32:] = 0.8
    out = through_webcam(frame, np.random.default_rng(1)).astype(np.float64)
    row = out[16:48, :, 1].mean(axis=0)
    step = np.diff(row)
    assert step.max() < 0.8 * (row[40:].mean() - row[:24].mean())  # not one pixel's step
    assert np.count_nonzero(step > 5.0) >= 2
