"""The per-pixel colour mixing (calib/fit/pixel.py mixing_tilde) on a channel the screen barely
reflects: where a colour pattern's rise over gray is lost in the camera's noise the pixel takes
the image's typical mixing; a pattern clearly darker than gray is still refused."""

from __future__ import annotations

import numpy as np
import pytest

from viewcomp.calib.errors import FitError
from viewcomp.calib.fit.pixel import mixing_tilde

H, W = 60, 120


def _captures(red_rise: np.ndarray) -> dict[str, np.ndarray]:
    """Linear captures: gray 0.3 (0.02 in red, a green screen), each colour pattern raising its
    own channel by 0.05, green and blue by 0.005 and red by 0.0001 otherwise; red's own rise
    ``red_rise`` (H, W)."""
    gray = np.empty((H, W, 3), np.float32)
    gray[...] = (0.02, 0.3, 0.3)
    caps = {"gray": gray}
    for j, name in enumerate(("red", "green", "blue")):
        img = gray + np.array([0.0001, 0.005, 0.005], np.float32)
        img[..., j] = gray[..., j] + (red_rise if j == 0 else 0.05)
        caps[name] = img.astype(np.float32)
    return caps


@pytest.mark.parametrize("wave", [1.4, 1.8])
def test_a_rise_lost_in_noise_takes_the_typical_mixing(wave: float) -> None:
    xx = np.arange(W, dtype=np.float64)[None, :].repeat(H, 0)
    # a rise of 0.001 that noise (here a slow wave) takes below 0 on a quarter to a third of
    # the pixels: down to -0.4 of its median, or -0.8 (beyond half the median, within three
    # of the wave's robust sigmas)
    rise = (0.001 * (1.0 + wave * np.sin(xx / 6.0))).astype(np.float32)
    wt = mixing_tilde(_captures(rise), 0.0, "screen")
    lost = rise <= 1e-5
    assert 0.2 < lost.mean() < 0.35
    assert np.all(np.isfinite(wt))
    assert np.allclose(wt[lost][:, 0, 0], 1.0)
    typical = np.median(wt[~lost][:, :, 0], axis=0)
    assert np.allclose(wt[lost][:, :, 0], typical)
    # the green and blue patterns' mixing, measured everywhere, is untouched: 0.005 / 0.05
    assert np.allclose(wt[..., 1, 2], 0.1, atol=1e-4) and np.allclose(wt[..., 2, 1], 0.1, atol=1e-4)


def test_a_pattern_clearly_darker_than_gray_is_refused() -> None:
    rise = np.full((H, W), 0.01, np.float32)
    rise[:, :6] = -0.01  # 10 % of the image: the red capture there is below gray
    with pytest.raises(FitError, match=r"screen/red.*darker than screen/gray"):
        mixing_tilde(_captures(rise), 0.0, "screen")
