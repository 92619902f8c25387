"""The per-pixel reach as a picture: per projector pixel the lowest and the highest colour it
can produce on the surface, as a viewer at an eye sees them.

The reach is :func:`viewcomp.calib.model.gamut.reach` of the per-pixel model's screen at the
eye (:func:`~viewcomp.calib.model.reference.screen_at`): the lowest colour is A (the
projector black, y = 0), the highest M 1 + A (every channel at full drive, y = 1). Beside
them the white screen at the projector's full output, the target those are measured against.
All three are on the preview's absolute scale (:func:`~viewcomp.calib.eval.preview.absolute_scale`:
the white screen's full output at :data:`~viewcomp.calib.eval.preview.REFERENCE_WHITE`) and
recorded as the calibration camera would (:func:`~viewcomp.calib.eval.preview.encode8`), so a
pixel of the highest panel darker or more coloured than the white panel is light the surface
cannot give back there, and a lowest panel above black is light it cannot take away.

Used by ``viewcomp preview --reach`` and by ``calibrate --report`` (``reach.png``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from viewcomp.calib.eval.preview import absolute_scale, band, encode8, labelled_row
from viewcomp.calib.fit.calibrate import Calibration
from viewcomp.calib.model.gamut import reach
from viewcomp.calib.model.reference import screen_at, white_response


@dataclass(frozen=True)
class ReachView:
    """The reach at one eye, encoded 8-bit as the calibration camera records (H, W, 3)
    uint8 each, and the mean linear level of each as a fraction of the white panel's."""

    white: np.ndarray
    lowest: np.ndarray
    highest: np.ndarray
    lowest_share: float
    highest_share: float


def reach_view(cal: Calibration, eye: np.ndarray) -> ReachView:
    """The :class:`ReachView` of the calibration's per-pixel model seen from ``eye`` (3,)
    metres."""
    model = cal.pixel.runtime_model()
    h, w = model.shape
    m, a = screen_at(model, np.asarray(eye, np.float64))
    r = reach(m, a)
    full = white_response(model, np.full((h, w, 3), 255, np.uint8)).astype(np.float64)
    k = absolute_scale(model, (h, w))
    level = max(float(full.mean()), 1e-12)
    return ReachView(
        encode8(cal, k * full),
        encode8(cal, k * r.lowest),
        encode8(cal, k * r.highest),
        float(np.mean(r.lowest)) / level,
        float(np.mean(r.highest)) / level,
    )


def reach_picture(cal: Calibration, eyes: list[tuple[str, np.ndarray]], title: str) -> np.ndarray:
    """The reach picture (uint8 RGB): a title band, then one labelled row per (label, eye):
    white screen at full output | highest colour | lowest colour."""
    rows = []
    for label, eye in eyes:
        v = reach_view(cal, eye)
        heads = [
            ["white screen, full output", label],
            ["highest (all channels full)", f"mean {v.highest_share:.2f} of white"],
            ["lowest (projector black)", f"mean {v.lowest_share:.3f} of white"],
        ]
        rows.append(labelled_row([v.white, v.highest, v.lowest], heads))
    body = np.concatenate(rows, axis=0)
    return np.concatenate([band(body.shape[1], [title]), body], axis=0)
