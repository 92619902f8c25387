"""The One-Euro filter (Casiez, Roussel and Vogel, CHI 2012): smoothing with little lag.

A first-order low-pass whose cutoff rises with the speed of the signal: at rest it smooths
hard (cutoff ``min_cutoff``, jitter removed), moving it follows closely (cutoff
``min_cutoff + beta |speed|``, lag small). Unlike a moving average its lag does not grow with
the amount of smoothing at speed.

Per sample at time t (seconds), with Te = t - t_prev and alpha(fc) = 1 / (1 + 1 / (2 pi fc Te)):

    speed   = (x - x_prev) / Te                 (raw consecutive samples)
    speed^  = speed^_prev + alpha(d_cutoff) (speed - speed^_prev)
    fc      = min_cutoff + beta |speed^|        (per component)
    x^      = x^_prev + alpha(fc) (x - x^_prev)

Closed forms the tests check: a constant input comes back unchanged; a step is approached
geometrically; a ramp of slope v is followed, once settled, with the constant lag
v / (2 pi (min_cutoff + beta |v|)).
"""

from __future__ import annotations

import math

import numpy as np


class OneEuroFilter:
    """One-Euro filter of a vector signal, each component on its own.

    Args:
        min_cutoff: cutoff at rest, Hz (> 0); lower: smoother at rest, more lag.
        beta: speed coefficient, Hz per (unit / s) (>= 0); higher: less lag when moving.
        d_cutoff: cutoff of the speed estimate, Hz (> 0).
    """

    def __init__(self, min_cutoff: float = 1.0, beta: float = 1.0, d_cutoff: float = 1.0):
        if not (min_cutoff > 0 and d_cutoff > 0 and beta >= 0):
            raise ValueError(
                f"One-Euro needs min_cutoff > 0, d_cutoff > 0, beta >= 0; got "
                f"{min_cutoff}, {d_cutoff}, {beta}"
            )
        self.min_cutoff = float(min_cutoff)
        self.beta = float(beta)
        self.d_cutoff = float(d_cutoff)
        self.reset()

    def reset(self) -> None:
        """Forget the past: the next sample is returned as it is."""
        self._t: float | None = None
        self._x: np.ndarray | None = None  # last raw sample
        self._y: np.ndarray | None = None  # last output
        self._dx: np.ndarray | None = None  # smoothed speed

    @staticmethod
    def alpha(cutoff: np.ndarray | float, te: float) -> np.ndarray:
        """The exponential smoothing factor 1 / (1 + tau / Te), tau = 1 / (2 pi cutoff)."""
        tau = 1.0 / (2.0 * math.pi * np.asarray(cutoff, np.float64))
        return 1.0 / (1.0 + tau / te)

    @property
    def value(self) -> np.ndarray | None:
        """The last output (a copy), or None before the first sample."""
        return None if self._y is None else self._y.copy()

    def __call__(self, x: np.ndarray | list[float], t: float) -> np.ndarray:
        """Filter sample ``x`` (any shape, float) taken at time ``t`` (seconds, increasing).

        The first sample (and one at a time not after the previous one) returns the current
        output unchanged in time: the first sample as it is, a repeated time stamp the
        previous output.
        """
        x = np.asarray(x, np.float64)
        if self._y is None or self._t is None or self._x is None:
            self._t, self._x, self._y = float(t), x.copy(), x.copy()
            self._dx = np.zeros_like(x)
            return x.copy()
        te = float(t) - self._t
        if te <= 0.0:
            return self._y.copy()
        assert self._dx is not None
        speed = (x - self._x) / te
        self._dx = self._dx + self.alpha(self.d_cutoff, te) * (speed - self._dx)
        cutoff = self.min_cutoff + self.beta * np.abs(self._dx)
        self._y = self._y + self.alpha(cutoff, te) * (x - self._y)
        self._t, self._x = float(t), x.copy()
        return self._y.copy()
