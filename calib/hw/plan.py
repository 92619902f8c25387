"""The plan of a camera-space capture: every pattern `viewcomp capture` shows, in order."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from viewcomp.calib.io.patterns import table1_patterns
from viewcomp.calib.sim.simcamera import geometric_patterns

TABLE1_ORDER = ("black", "gray", "red", "green", "blue", "ramp")


@dataclass(frozen=True)
class Step:
    """One capture: the folder (``"white"`` or ``"screen"``), its name and the (H, W, 3) uint8
    pattern to show."""

    sub: str
    name: str
    pattern: np.ndarray


def capture_plan(width: int, height: int) -> list[Step]:
    """Every capture of a camera-space set, in order, for a width x height projector."""
    t1 = table1_patterns(width, height)
    geo = geometric_patterns(width, height)
    steps = [Step("white", n, t1[n]) for n in TABLE1_ORDER]
    steps.append(Step("white", "chessboard", geo["chessboard"]))
    steps += [Step("screen", n, t1[n]) for n in TABLE1_ORDER]
    steps += [Step("screen", n, p) for n, p in geo.items()]
    return steps
