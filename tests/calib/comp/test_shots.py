"""Cut detection and the adaptive field's smoothing within a shot."""

from __future__ import annotations

import numpy as np

from viewcomp.calib.comp.shots import FieldSmoother
from viewcomp.calib.model.gamut import ToneField


def _thumb(level: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.clip(level + rng.integers(-10, 11, (32, 64, 3)), 0, 255).astype(np.uint8)


def test_cuts_are_new_content_not_noise() -> None:
    s = FieldSmoother(0.5)
    assert s.is_cut(_thumb(100))  # the first frame starts a shot
    assert not s.is_cut(_thumb(102, seed=1))  # the same shot, a little noise
    assert s.is_cut(_thumb(200, seed=2))
    assert not s.is_cut(_thumb(198, seed=3))


def test_within_a_shot_the_field_eases_and_at_a_cut_it_jumps() -> None:
    s = FieldSmoother(0.5)
    a, b = ToneField.uniform(1.0, 0.0, (3, 5)), ToneField.uniform(0.5, 0.0, (3, 5))
    assert s.update(0.0, a, cut=True).gain[0, 0] == 1.0
    one = s.update(1 / 24, b, cut=False).gain[0, 0]
    assert 0.95 < one < 1.0  # exp(-1 / 12) of the way stays
    assert abs(one - (1.0 - 0.5 * (1 - np.exp(-1 / 12)))) < 1e-12
    assert s.update(2 / 24, b, cut=True).gain[0, 0] == 0.5  # settled at once
