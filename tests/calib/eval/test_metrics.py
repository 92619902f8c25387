"""Error measures on 8-bit encoded RGB images."""

from __future__ import annotations

import math

import numpy as np
import pytest

from viewcomp.calib.eval.metrics import delta_e2000, psnr, sse, ssim


def _img(seed: int, h: int = 16, w: int = 24) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 256, (h, w, 3)).astype(np.uint8)


def test_identical_images() -> None:
    a = _img(0)
    assert sse(a, a) == 0.0
    assert psnr(a, a) == math.inf
    assert ssim(a, a) == pytest.approx(1.0)
    assert delta_e2000(a, a) == pytest.approx(0.0, abs=1e-9)


def test_sse_and_psnr_by_hand() -> None:
    a = np.array([[[0, 0, 0], [10, 20, 30]]], np.uint8)
    b = np.array([[[1, 2, 3], [10, 20, 30]]], np.uint8)
    # Eq. 26: 1^2 + 2^2 + 3^2 = 14, in 8-bit units squared; no uint8 wrap-around
    assert sse(a, b) == 14.0
    assert sse(b, a) == 14.0
    assert psnr(a, b) == pytest.approx(10 * math.log10(255**2 / (14 / 6)))
    black = np.zeros((2, 2, 3), np.uint8)
    white = np.full((2, 2, 3), 255, np.uint8)
    assert sse(black, white) == 255.0**2 * 12
    assert psnr(black, white) == pytest.approx(0.0)


def test_ssim_orders_distortions() -> None:
    a = _img(1, 32, 32)
    noisy = np.clip(a.astype(int) + np.random.default_rng(2).integers(-20, 21, a.shape), 0, 255)
    far = _img(3, 32, 32)
    s_near, s_far = ssim(a, noisy.astype(np.uint8)), ssim(a, far)
    assert 1.0 > s_near > s_far


def test_delta_e2000_black_white_and_small() -> None:
    black = np.zeros((4, 4, 3), np.uint8)
    white = np.full((4, 4, 3), 255, np.uint8)
    assert delta_e2000(black, white) == pytest.approx(100.0, abs=0.01)
    grey = np.full((4, 4, 3), 128, np.uint8)
    assert 0.0 < delta_e2000(grey, grey + 1) < 1.0  # one level is barely visible


def test_refusals() -> None:
    a = _img(0)
    with pytest.raises(ValueError, match="uint8"):
        sse(a.astype(np.float32), a)
    with pytest.raises(ValueError, match="differ in size"):
        psnr(a, a[:8])
    with pytest.raises(ValueError, match=r"\(H, W, 3\)"):
        delta_e2000(a[..., 0], a[..., 0])
    with pytest.raises(ValueError, match="7x7"):
        ssim(a[:5, :5], a[:5, :5])
