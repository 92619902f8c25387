"""A mono camera's set in the per-primary basis: the mono captures are made here from known
per-pixel primary gains, per-primary responses (unequal gammas) and ambient, light adding up;
the per-primary captures must give back each primary's own light."""

from __future__ import annotations

import numpy as np
import pytest

from viewcomp.calib.errors import FitError
from viewcomp.calib.fit.mono import per_primary_images
from viewcomp.calib.io.patterns import primary_patterns, table1_patterns

W, H = 64, 32
GAMMA = np.array([2.3, 2.1, 2.5])


def _world(cross: float = 0.0) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray]:
    """Mono captures of every pattern: Y = A + sum_j g_j f_j(I_j) (+ ``cross`` g_0 f_1(I_1):
    light of green seen as more red, which the per-primary model cannot hold)."""
    yy, xx = np.mgrid[0:H, 0:W] / max(W, H)
    gains = np.stack([0.5 + 0.3 * xx, 0.8 - 0.2 * yy, 0.3 + 0.1 * xx * yy], axis=-1)
    ambient = 0.02 + 0.01 * xx
    pats = {**table1_patterns(W, H), **primary_patterns(W, H)}
    out = {}
    for name, p in pats.items():
        f = (p.astype(np.float64) / 255.0) ** GAMMA
        y = ambient + (gains * f).sum(axis=-1) + cross * gains[..., 0] * f[..., 1]
        out[name] = np.repeat(y[..., None], 3, axis=2).astype(np.float32)
    return out, gains, ambient


def test_each_channel_is_its_primary_alone() -> None:
    mono, gains, ambient = _world()
    per, additivity = per_primary_images(mono, "screen")
    assert additivity < 1e-5
    ramp = table1_patterns(W, H)["ramp"][..., 0].astype(np.float64) / 255.0
    for j in range(3):
        want = gains[..., j] * ramp ** GAMMA[j] + ambient / 3
        assert np.allclose(per["ramp"][..., j], want, atol=1e-5)
        want_gray = gains[..., j] * (110 / 255) ** GAMMA[j] + ambient / 3
        assert np.allclose(per["gray"][..., j], want_gray, atol=1e-5)
    # red raises only its own channel, by what the red step adds
    d = per["red"] - per["gray"]
    step = gains[..., 0] * ((130 / 255) ** GAMMA[0] - (110 / 255) ** GAMMA[0])
    assert np.allclose(d[..., 0], step, atol=1e-5)
    assert np.abs(d[..., 1:]).max() < 1e-6
    assert np.allclose(per["black"].sum(axis=-1), ambient, atol=1e-6)


def test_light_that_does_not_add_up_is_measured() -> None:
    mono, _, _ = _world(cross=0.3)
    mono["gray"] = mono["gray"] * np.float32(1.1)  # the gray is not the primaries' sum
    _, additivity = per_primary_images(mono, "white")
    assert additivity > 0.05


def test_a_mono_set_without_the_primaries_is_refused() -> None:
    mono, _, _ = _world()
    del mono["ramp_green"]
    with pytest.raises(FitError, match=r"white/ramp_green.*capture the set again"):
        per_primary_images(mono, "white")
