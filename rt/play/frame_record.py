"""What one frame of :class:`~viewcomp.rt.play.embed.LiveRenderer` used: :class:`FrameRecord`."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from viewcomp.calib.comp.compensation import FrameParams
from viewcomp.calib.model.reference import View
from viewcomp.calib.world.audience import Audience


@dataclass(frozen=True)
class FrameRecord:
    """What one rendered frame used: the eye (3,) metres, the FrameParams, the time (s).

    ``tone_eye`` is the eye (or audience) the FrameParams were computed for (the tone map
    and, for the paper's method, the model); with ``async_tone`` it can lag ``eye`` by a few
    frames. ``audience``: the viewers compensated for when there were several (``eye`` is
    then their weighted mean), else None.
    """

    eye: np.ndarray
    params: FrameParams
    time: float
    tone_eye: View
    identity: bool
    audience: Audience | None = None
