"""A single-chip DLP projector's light over time: colour sub-frames, PWM bit planes, response.

Within every refresh period P = 1 / ``refresh_hz`` the projector shows the sub-frames of
``sequence`` in turn (``"RGBRGB"``: a colour wheel turning twice per refresh; ``"RGB"``: LED
sub-frames; a ``W`` is a white segment). Each segment occupies an equal share of the period;
its first ``spoke`` fraction is dark (the wheel's spoke passing the lamp), the rest shows the
segment channel's PWM code as ``pwm_bits`` bit planes, most significant first, bit b lit for
2^b / (2^B - 1) of the active time when the code has bit b set.

Levels to codes, per channel j (input level I in 0..255, x = I / 255):

    h(x)   = (((x + a) / (1 + a))^g_j - c_j) / (1 - c_j),  c_j = (a / (1 + a))^g_j
    code_j = round((2^B - 1) h(x))

an offset power law (``toe`` = a): near black it is close to a straight line instead of the
simulator's pure power x^g, so dark levels come out brighter than a power law predicts. The
white segment shows code_W = round((2^B - 1) h_W(min_j I_j / 255)) (h_W with the mean
gamma), the "brilliant colour" boost of bright unsaturated pixels.

Emission: while channel j's segment is on screen a pixel emits (leak_j + (1 - leak_j) m) / d_j
of that primary, m = 1 when its mirror is on (the bit plane's bit is set) and 0 otherwise;
d_j is the fraction of the period channel j's segments are active. Averaged over a whole
period this is leak_j + (1 - leak_j) code_j / (2^B - 1): :meth:`DlpModel.steady`, the light the
audience sees. The white segment emits ``white_gain`` code_W / (2^B - 1) / d_W of every
primary (no leak).

A camera integrates the emission over its exposure window [t0, t1]. Every bit plane of every
segment is a periodic interval [s, s + l) (mod P), whose overlap with [t0, t1] is
F(t1) - F(t0) with F(t) = floor(t / P) l + clip((t mod P) - s, 0, l): the integral is exact
and needs no time stepping (:meth:`DlpModel.drive_luts`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

CHANNELS = "RGBW"


@dataclass(frozen=True)
class DlpModel:
    """The projector's time-varying light (see the module doc).

    ``refresh_hz``: refresh rate (Hz). ``sequence``: sub-frames of one refresh, letters of
    ``RGBW``, each of R, G and B at least once. ``spoke``: dark fraction at the start of each
    segment, 0..0.5. ``pwm_bits``: bit planes per segment, 1..12. ``gamma`` (3,), ``toe``
    (a >= 0), ``leak`` (3,) fraction of full light at level 0: the response. ``white_gain``:
    light of a full white segment, relative to a full primary (used only with a ``W``).
    """

    refresh_hz: float = 60.0
    sequence: str = "RGBRGB"
    spoke: float = 0.04
    pwm_bits: int = 10
    gamma: tuple[float, float, float] = (2.3, 2.1, 2.5)
    toe: float = 0.05
    leak: tuple[float, float, float] = (0.006, 0.007, 0.008)
    white_gain: float = 0.3

    def __post_init__(self) -> None:
        if not (math.isfinite(self.refresh_hz) and self.refresh_hz > 0):
            raise ValueError(f"refresh_hz must be > 0, got {self.refresh_hz}")
        seq = self.sequence.upper()
        if not seq or any(c not in CHANNELS for c in seq) or any(c not in seq for c in "RGB"):
            raise ValueError(
                f"a DLP sequence is letters of R, G, B, W with each of R, G, B at least once "
                f"(e.g. RGBRGB, RGBW), got {self.sequence!r}"
            )
        if not 0 <= self.spoke <= 0.5:
            raise ValueError(f"spoke is a fraction of a segment in 0..0.5, got {self.spoke}")
        if not 1 <= self.pwm_bits <= 12:
            raise ValueError(f"pwm_bits must be 1..12, got {self.pwm_bits}")
        if self.toe < 0 or any(g <= 0 for g in self.gamma):
            raise ValueError(f"toe must be >= 0 and gamma > 0, got {self.toe}, {self.gamma}")
        if any(not 0 <= v < 1 for v in self.leak):
            raise ValueError(f"leak is three fractions in 0..1, got {self.leak}")

    @property
    def period(self) -> float:
        """One refresh period P in seconds."""
        return 1.0 / self.refresh_hz

    @property
    def cmax(self) -> int:
        """The largest PWM code, 2^B - 1."""
        return (1 << self.pwm_bits) - 1

    # -- the response ----------------------------------------------------------------------

    def _h(self, x: np.ndarray, g: float) -> np.ndarray:
        a = self.toe
        c = (a / (1.0 + a)) ** g
        return (((x + a) / (1.0 + a)) ** g - c) / (1.0 - c)

    @cached_property
    def codes(self) -> np.ndarray:
        """(4, 256) int64: the PWM code of every input level, per channel R, G, B, W."""
        x = np.arange(256, dtype=np.float64) / 255.0
        gammas = (*self.gamma, float(np.mean(self.gamma)))
        return np.stack([np.rint(self.cmax * self._h(x, g)).astype(np.int64) for g in gammas])

    def steady(self, levels: np.ndarray) -> np.ndarray:
        """The light averaged over whole refresh periods: levels (..., 3) 0..255 -> (..., 3)
        float64 per primary (1 = a full primary; the white segment adds to all three)."""
        lv = np.clip(np.rint(np.asarray(levels, np.float64)), 0, 255).astype(np.int64)
        leak = np.asarray(self.leak, np.float64)
        out = leak + (1.0 - leak) * np.stack(
            [self.codes[j][lv[..., j]] for j in range(3)], axis=-1
        ) / float(self.cmax)
        if "W" in self.sequence.upper():
            w = self.codes[3][lv.min(axis=-1)] / float(self.cmax)
            out = out + self.white_gain * w[..., None]
        return out

    # -- the time structure ------------------------------------------------------------------

    @cached_property
    def intervals(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Every bit plane of every segment in one period: (start s, length l) in seconds from
        the start of the period, channel (0..3 = R, G, B, W) and bit; each (K,)."""
        seq = self.sequence.upper()
        seg = self.period / len(seq)
        active = seg * (1.0 - self.spoke)
        weights = np.array([1 << b for b in range(self.pwm_bits)], np.float64) / self.cmax
        starts, lengths, chans, bits = [], [], [], []
        for k, ch in enumerate(seq):
            t = k * seg + seg * self.spoke
            for b in reversed(range(self.pwm_bits)):  # most significant first
                ln = active * weights[b]
                starts.append(t)
                lengths.append(ln)
                chans.append(CHANNELS.index(ch))
                bits.append(b)
                t += ln
        return (np.array(starts), np.array(lengths), np.array(chans), np.array(bits))

    @cached_property
    def duty(self) -> np.ndarray:
        """(4,) fraction of the period each channel's segments are active (0: absent)."""
        _, lengths, chans, _ = self.intervals
        return np.array([lengths[chans == c].sum() for c in range(4)]) / self.period

    def overlaps(self, t0: np.ndarray, t1: np.ndarray) -> np.ndarray:
        """Seconds each bit-plane interval is on screen within windows [t0, t1]: (N,) each ->
        (N, K) (K as :attr:`intervals`); a window with t1 <= t0 gets zeros."""
        s, ln, _, _ = self.intervals
        p = self.period
        a = np.asarray(t0, np.float64)[:, None]
        b = np.maximum(np.asarray(t1, np.float64)[:, None], a)

        def f(t: np.ndarray) -> np.ndarray:
            n = np.floor(t / p)
            return n * ln + np.clip(t - n * p - s, 0.0, ln)

        return f(b) - f(a)

    def drive_luts(self, t0: np.ndarray, t1: np.ndarray) -> np.ndarray:
        """The integral of the emission over windows [t0, t1], per input level: (N,) windows
        -> (N, 4, 256) float64 in seconds of full primary light, channels R, G, B, W. A pixel
        showing level I in channel j for the whole window emits ``lut[n, j, I]`` of primary j
        (the W entry: of white, already times ``white_gain``; index it by min_j I_j)."""
        ov = self.overlaps(t0, t1)
        _, _, chans, bits = self.intervals
        n = ov.shape[0]
        b = self.pwm_bits
        per_bit = np.zeros((n, 4, b))
        np.add.at(per_bit, (slice(None), chans, bits), ov)  # type: ignore[arg-type]
        code_bits = (self.codes[:, :, None] >> np.arange(b)) & 1  # (4, 256, B)
        lit = np.einsum("jib,njb->nji", code_bits.astype(np.float64), per_bit)
        seg_time = per_bit.sum(axis=2)  # (N, 4) the window's time in each channel's segments
        leak = np.array([*self.leak, 0.0])
        gain = np.array([1.0, 1.0, 1.0, self.white_gain])
        duty = np.where(self.duty > 0, self.duty, 1.0)
        out = leak[None, :, None] * seg_time[:, :, None] + (1.0 - leak)[None, :, None] * lit
        return out * (gain / duty)[None, :, None]
