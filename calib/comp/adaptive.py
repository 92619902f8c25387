"""Choosing the adaptive tone map (:mod:`~viewcomp.calib.model.gamut`) for a frame.

The field's gain and offset at its nodes minimise the *predicted adapted* error of the
thumbnail: the screen's prediction M y + A of the light y the soft clip asks for, compared
with the white screen's C_w by the mean CIE94 difference after the best uniform brightness
scale s in [1/4, 4] (half stops), as the evaluation's adapted CIEDE2000 compares what the
eye sees (:mod:`~viewcomp.calib.eval.adapted`; CIE94 and a coarse s for speed), plus a small
price on the field's roughness (the squared differences of neighbouring nodes' log gains), so
that it stays smooth where the error does not care.

The search: the best uniform gain (offset 0) on a quarter-stop grid (hue weights
:data:`FIRST_HUES`), and the global tone map's (alpha, beta) if given - with the soft clip
and as the global rule exactly (hue weight 0) - whichever predicts less; then rounds of a
coordinate search over the nodes (each node's gain times 2^(+-step), its offset +- a step of
the mean white level) and the hue weight (+- a step, in [0, 1]), the steps halving each
round. A video frame starts from the last frame's field with the smallest steps (a local
search). Where the screen shows nearly every colour (a white or pale screen) the global rule
predicts less and the search keeps it.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from viewcomp.calib.comp.tonemap import delta_e94, linear_lab
from viewcomp.calib.model.gamut import LUMA, ToneField, field_at, grey_range, soft_light

#: The field's nodes (rows, columns): the gain and offset change over about a quarter of the
#: image's width and half its height at the most.
NODES = (3, 5)
#: The price of the field's roughness, per squared stop between neighbouring nodes.
SMOOTH_WEIGHT = 2.0
#: Scales s of the predicted adapted error (half stops over [1/4, 4]).
SCALES = 2.0 ** np.arange(-2.0, 2.01, 0.5)
_SCALES_4D = SCALES[:, None, None, None]
GAIN_MIN, GAIN_MAX = 0.05, 4.0
#: Hue weights of the first stage's uniform fields: the weight trades against the gain (a
#: dimmer field presses less), so each gain is tried with the soft clip whole and half mixed
#: (green-plastic, 320x160: -25.5 % against the global rule's adapted dE, -24.9 % with the
#: whole clip alone).
FIRST_HUES = (1.0, 0.5)


class SearchStopped(Exception):
    """A node search given up because its ``stop`` said so (the caller has newer work)."""


class AdaptedPrediction:
    """The predicted adapted error of a field on a thumbnail's pixels (module docstring).

    Args:
        u, v, c: (h, w, 3) :func:`~viewcomp.calib.model.reference.tone_terms` on the
            thumbnail's pixels.
        m, a: (h, w, 3, 3) and (h, w, 3) the screen at the eye there.
        cw: (h, w, 3) C_w there (linear camera units).
    """

    def __init__(
        self,
        u: np.ndarray,
        v: np.ndarray,
        c: np.ndarray,
        m: np.ndarray,
        a: np.ndarray,
        cw: np.ndarray,
    ) -> None:
        f32 = np.float32
        self.shape = u.shape[:2]
        self.u, self.v, self.c = u.astype(f32), v.astype(f32), c.astype(f32)
        self.m, self.a = m.astype(np.float64), a.astype(np.float64)
        self.luma = (cw @ LUMA).astype(f32)
        self.lo, self.hi = grey_range(self.v, self.c)
        self.goal = linear_lab(np.clip(cw, 0.0, 1.0))
        self.level = max(float(np.mean(cw)), 1e-4)

    def seen(self, field: ToneField) -> np.ndarray:
        """The predicted screen (h, w, 3) for ``field``."""
        g, o = field_at(field, self.shape)
        y = soft_light(self.u, self.v, self.c, self.luma, g, o, self.lo, self.hi, field.hue)
        return np.einsum("hwij,hwj->hwi", self.m, y.astype(np.float64)) + self.a

    def __call__(self, field: ToneField) -> float:
        """Predicted adapted error plus the roughness price."""
        # what the eye sees saturates first (the camera's range: seen is clipped there
        # before the eye adapts), then the best scale
        seen = np.clip(self.seen(field), 0.0, 1.0)
        # every scale at once: (len(SCALES), h, w, 3); one mean per scale
        scaled = np.clip(_SCALES_4D * seen, 0.0, 1.0)
        de = delta_e94(linear_lab(scaled), self.goal)
        err = min(float(np.mean(d)) for d in de)
        lg = np.log2(np.maximum(field.gain, 1e-6))
        rough = float(np.sum(np.diff(lg, axis=0) ** 2) + np.sum(np.diff(lg, axis=1) ** 2))
        return err + SMOOTH_WEIGHT * rough / max(lg.size, 1)


def _node_search(
    pred: AdaptedPrediction,
    field: ToneField,
    cost: float,
    steps: list[tuple[float, float]],
    stop: Callable[[], bool] | None = None,
) -> tuple[ToneField, float]:
    """Coordinate search over the nodes and the hue weight, one (gain stops, offset
    fraction) step pair per round (the hue weight's step: the gain's stops). ``stop`` is
    asked before each node; True raises :class:`SearchStopped`."""
    gain, offset, hue = field.gain.copy(), field.offset.copy(), float(field.hue)
    for gstep, ostep in steps:
        for idx in np.ndindex(gain.shape):
            if stop is not None and stop():
                raise SearchStopped
            for which, deltas in (
                ("g", (2.0**gstep, 2.0**-gstep)),
                ("o", (ostep * pred.level, -ostep * pred.level)),
            ):
                for d in deltas:
                    g2, o2 = gain.copy(), offset.copy()
                    if which == "g":
                        g2[idx] = float(np.clip(g2[idx] * d, GAIN_MIN, GAIN_MAX))
                    else:
                        o2[idx] += d
                    trial = pred(ToneField(g2, o2, hue))
                    if trial < cost - 1e-9:
                        gain, offset, cost = g2, o2, trial
                        break
        for d in (gstep, -gstep):
            h2 = float(np.clip(hue + d, 0.0, 1.0))
            trial = pred(ToneField(gain, offset, h2)) if h2 != hue else np.inf
            if trial < cost - 1e-9:
                hue, cost = h2, trial
                break
    return ToneField(gain, offset, hue), cost


def choose_field(
    pred: AdaptedPrediction,
    global_tone: tuple[float, float] | None = None,
    start: ToneField | None = None,
    nodes: tuple[int, int] = NODES,
    early: Callable[[ToneField], None] | None = None,
    stop: Callable[[], bool] | None = None,
) -> ToneField:
    """The field for a thumbnail (module docstring): a whole search, or with ``start`` (the
    last video frame's field) a local one. ``early``: a whole search calls it with its first
    stage's field (the best uniform one, about a fifth of the search's cost) before the
    node search. ``stop``: asked during the node search; True gives the search up
    (:class:`SearchStopped`)."""
    if start is not None:
        return _node_search(pred, start, pred(start), [(0.125, 0.01)], stop)[0]
    best, cost = None, np.inf
    for t in np.arange(-3.0, 1.51, 0.25):
        for hue in FIRST_HUES:
            f = ToneField.uniform(float(2.0**t), 0.0, nodes, hue)
            e = pred(f)
            if e < cost:
                best, cost = f, e
    if global_tone is not None:
        for hue in (1.0, 0.0):
            f = ToneField.uniform(global_tone[0], global_tone[1], nodes, hue)
            e = pred(f)
            if e < cost:
                best, cost = f, e
    assert best is not None
    if early is not None:
        early(best)
    return _node_search(pred, best, cost, [(0.5, 0.04), (0.25, 0.02), (0.125, 0.01)], stop)[0]
