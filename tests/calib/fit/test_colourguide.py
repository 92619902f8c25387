"""The per-pixel colour mixing, and the gains' shares, smoothed where the screen's colour is
uniform (calib/fit/colourguide.py through calib/fit/pixel.py mixing_tilde; smooth_shares).

The captures are built here from two known mixing matrices (an orange and a blue region of a
screen, a vignetting gradient over both, independent noise in every capture), not by the code
under test: the guided mixing must average the noise inside each region and keep the step at
the colour edge, where a Gaussian as wide would smear it."""

from __future__ import annotations

import numpy as np
import pytest

from viewcomp.calib.fit.colourguide import (
    colour_guide,
    colour_smoother,
    guided_filter,
    smooth_shares,
)
from viewcomp.calib.fit.pixel import mixing_tilde

H, W = 96, 192
EDGE = W // 2
NOISE = 0.004
GUIDE = 32  # the window radius calibrate --colour-guide-px takes for a webcam
#: Per region: the mixing M (camera channel i from projector channel j) and the albedo.
MIXING = (
    (np.array([[1.0, 0.12, 0.03], [0.10, 1.0, 0.15], [0.02, 0.09, 1.0]]), (0.8, 0.45, 0.15)),
    (np.array([[1.0, 0.05, 0.10], [0.18, 1.0, 0.06], [0.04, 0.20, 1.0]]), (0.2, 0.4, 0.85)),
)
GRAY, RISE = 0.3, 0.5  # the gray pattern's linear drive; a colour pattern adds RISE to its own


def _truth() -> tuple[np.ndarray, np.ndarray]:
    """Per-pixel W (H, W, 3, 3) and the true W~ (its columns over their own diagonal)."""
    w = np.empty((H, W, 3, 3))
    for k, (m, albedo) in enumerate(MIXING):
        cols = slice(0, EDGE) if k == 0 else slice(EDGE, W)
        w[:, cols] = np.diag(albedo) @ m
    wt = w / np.einsum("...jj->...j", w)[..., None, :]
    return w, wt


def _captures(seed: int) -> dict[str, np.ndarray]:
    w, _ = _truth()
    yy, xx = np.mgrid[0:H, 0:W]
    vignette = 1.0 - 0.35 * (((xx - W / 2) / W) ** 2 + ((yy - H / 2) / H) ** 2)
    rng = np.random.default_rng(seed)
    drives = {"gray": np.full(3, GRAY)}
    for j, name in enumerate(("red", "green", "blue")):
        drives[name] = np.full(3, GRAY) + RISE * np.eye(3)[j]
    caps = {}
    for name, drive in drives.items():
        light = vignette[..., None] * np.einsum("hwij,j->hwi", w, drive) + 0.01
        caps[name] = (light + rng.normal(0.0, NOISE, light.shape)).astype(np.float32)
    return caps


def _off_diagonal(wt: np.ndarray) -> np.ndarray:
    return wt[..., ~np.eye(3, dtype=bool)]


@pytest.mark.parametrize("seed", [1, 2])
def test_noise_inside_a_colour_region_is_averaged(seed: int) -> None:
    _, truth = _truth()
    caps = _captures(seed)
    inner = np.zeros((H, W), bool)
    # beyond the window's reach of the colour edge
    inner[8:-8, 8 : EDGE - GUIDE - 8] = inner[8:-8, EDGE + GUIDE + 8 : -8] = True
    guided = _off_diagonal(
        mixing_tilde(caps, 3.0, "screen", colour_smoother(caps["gray"], GUIDE)) - truth
    )[inner]
    plain = _off_diagonal(mixing_tilde(caps, 3.0, "screen") - truth)[inner]
    rms_guided = float(np.sqrt(np.mean(guided**2)))
    rms_plain = float(np.sqrt(np.mean(plain**2)))
    # measured (seeds 1-3): 0.0022-0.0024 guided, 0.0044-0.0047 with the 3 px Gaussian alone
    assert rms_guided < 0.6 * rms_plain
    assert rms_guided < 0.003


def test_a_colour_edge_keeps_its_step() -> None:
    _, truth = _truth()
    caps = _captures(3)
    near = np.zeros((H, W), bool)
    near[8:-8, EDGE - 6 : EDGE - 2] = near[8:-8, EDGE + 2 : EDGE + 6] = True
    step = float(np.max(np.abs(_off_diagonal(truth[0, 0] - truth[0, -1]))))
    guided = np.abs(
        _off_diagonal(
            mixing_tilde(caps, 3.0, "screen", colour_smoother(caps["gray"], GUIDE)) - truth
        )
    )[near]
    wide = np.abs(_off_diagonal(mixing_tilde(caps, 16.0, "screen") - truth))[near]
    # measured (seeds 1-3): 2-6 px from the edge the guided mixing is at most 0.22-0.24 of
    # the step off; a Gaussian of 16 px (noise 0.0019-0.0021 inside, about the guided
    # mixing's) 0.82 of it
    assert float(np.max(guided)) < 0.35 * step
    assert float(np.max(wide)) > 0.6 * step


def test_the_guide_is_the_chromaticity_and_radius_zero_is_the_identity() -> None:
    gray = np.zeros((4, 16, 3), np.float32)
    gray[:, :8] = (0.2, 0.4, 0.6)
    guide = colour_guide(gray)
    assert np.allclose(guide[:, 0], (0.5, 1.0, 1.5), atol=1e-5)
    assert np.allclose(guide[:, -1], 1.0)  # dark: neutral
    img = np.random.default_rng(0).random((4, 16, 2)).astype(np.float32)
    assert np.array_equal(colour_smoother(gray, 0)(img), img)
    with pytest.raises(ValueError, match="radius"):
        colour_smoother(gray, -1)
    with pytest.raises(ValueError, match="gray"):
        colour_guide(gray[..., :2])


@pytest.mark.parametrize("eps", [1e-6, 1e-4, 1e-2])
def test_the_guided_filter_follows_the_closed_form(eps: float) -> None:
    """In a region where the guide varies by noise of variance v along one channel and not at
    all along the others, the filter of the guide itself is the window mean plus
    v / (v + eps) of each pixel's deviation (He et al.'s closed form)."""
    rng = np.random.default_rng(0)
    v = 1e-4
    i = 1.0 + np.sqrt(v) * rng.standard_normal((200, 200))
    guide = np.dstack([i, np.ones_like(i), np.ones_like(i)])
    q = guided_filter(guide, i[..., None], 10, eps)[..., 0]
    slope = np.polyfit((i - i.mean()).ravel(), (q - q.mean()).ravel(), 1)[0]
    assert slope == pytest.approx(v / (v + eps), abs=0.01)


def _gains(seed: int, noise: float) -> tuple[np.ndarray, np.ndarray]:
    """True per-pixel gains (H, W, 3): the two regions' albedos times a lightness texture
    (stripes of +-25 %, the same in every channel), and a noisy measurement of them
    (independent noise per channel, as three separate captures give)."""
    _, xx = np.mgrid[0:H, 0:W]
    texture = 1.0 + 0.25 * np.sign(np.sin(xx / 3.0))
    albedo = np.where((xx < EDGE)[..., None], MIXING[0][1], MIXING[1][1])
    truth = texture[..., None] * albedo
    rng = np.random.default_rng(seed)
    return truth, (truth + rng.normal(0.0, noise, truth.shape)).astype(np.float32)


def _shares(d: np.ndarray) -> np.ndarray:
    return d / d.sum(axis=-1, keepdims=True)


@pytest.mark.parametrize("seed", [1, 2])
def test_the_gains_keep_their_sum_and_lose_their_colour_noise(seed: int) -> None:
    """The gains' per-pixel sum (the texture) is kept exactly; the shares' noise inside a
    region is averaged; the shares keep their step at the colour edge."""
    truth, noisy = _gains(seed, 0.02)
    out = smooth_shares(noisy, colour_smoother(noisy, GUIDE))
    assert np.allclose(out.sum(axis=-1), noisy.sum(axis=-1), rtol=1e-5)
    inner = np.zeros((H, W), bool)
    inner[8:-8, 8 : EDGE - GUIDE - 8] = inner[8:-8, EDGE + GUIDE + 8 : -8] = True
    err = (_shares(out) - _shares(truth))[inner]
    raw = (_shares(noisy) - _shares(truth))[inner]
    rms, rms_raw = float(np.sqrt(np.mean(err**2))), float(np.sqrt(np.mean(raw**2)))
    # measured (seeds 1-3): the shares' noise 0.0135-0.0136 as measured, 0.0014 smoothed
    assert rms < 0.2 * rms_raw, (rms, rms_raw)
    near = np.zeros((H, W), bool)
    near[8:-8, EDGE - 6 : EDGE - 2] = near[8:-8, EDGE + 2 : EDGE + 6] = True
    step = float(np.max(np.abs(_shares(truth)[0, 0] - _shares(truth)[0, -1])))
    off = float(np.max(np.abs(_shares(out) - _shares(truth))[near]))
    # measured (seeds 1-3): 2-6 px from the edge at most 0.03-0.04 of the step off
    assert off < 0.15 * step, (off, step)


def test_a_channel_the_screen_barely_reflects_keeps_a_positive_gain() -> None:
    """Noise about 0 in a channel (a green screen's red): the smoothed gains stay positive,
    so the per-pixel model can be inverted, and the sum is still kept."""
    rng = np.random.default_rng(0)
    d = np.empty((H, W, 3), np.float32)
    d[...] = (0.0, 0.5, 0.1)
    d[..., 0] = rng.normal(0.0, 0.003, (H, W))
    out = smooth_shares(d, colour_smoother(np.maximum(d, 0.0), GUIDE))
    assert float(out[..., 0].min()) > 0.0
    assert np.allclose(out.sum(axis=-1), d.sum(axis=-1), rtol=1e-5)


def test_dark_pixels_keep_their_gains_and_a_uniform_colour_is_unchanged() -> None:
    d = np.zeros((4, 12, 3), np.float32)
    d[:, :6] = (0.2, 0.3, 0.1)
    d[0, 8] = (-0.01, 0.0, 0.0)  # noise about 0 where nothing is lit
    out = smooth_shares(d, colour_smoother(d, 1))
    assert np.array_equal(out[:, 6:], d[:, 6:])
    # beyond the windows' reach of the dark part (radius 1: two windows)
    assert np.allclose(out[:, :4], d[:, :4], atol=1e-6)
