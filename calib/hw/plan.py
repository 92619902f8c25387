"""The plan of a camera-space capture: every pattern `viewcomp capture` shows, in order.

Each stage's reference pattern (:data:`REFERENCE`, gray) is shown again every
:data:`REFERENCE_EVERY` captures: those steps are ``check_only`` (compared with the stage's
first gray and the one shown before, like with like, so a bump or a slow drift of the camera
shows between two of them; not written into the capture set). They never split a Gray-code
plane from its inverse, and the procedure shows the reference once more at each stage's end.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from viewcomp.calib.io.patterns import (
    CAMERA_COLOUR_LEVEL,
    primary_patterns,
    table1_patterns,
)
from viewcomp.calib.sim.simcamera import geometric_patterns

TABLE1_ORDER = ("black", "gray", "red", "green", "blue", "ramp")
REFERENCE = "gray"  # each stage's reference for the camera-moved check
REFERENCE_EVERY = 6  # captures between two showings of the reference


@dataclass(frozen=True)
class Step:
    """One capture: the folder (``"white"`` or ``"screen"``), its name and the (H, W, 3) uint8
    pattern to show; ``check_only``: checked as it arrives but not written (the reference
    shown again)."""

    sub: str
    name: str
    pattern: np.ndarray
    check_only: bool = False


def reference_again(after: str) -> str:
    """The name of the reference shown again after capture ``after`` (a check-only step)."""
    return f"{REFERENCE} (again, after {after})"


def is_reference_again(name: str) -> bool:
    """Whether ``name`` is a reference shown again (:func:`reference_again`, or the
    procedure's own at a stage's end)."""
    return name.startswith(f"{REFERENCE} (again")


def capture_plan(width: int, height: int, mono: bool = False) -> list[Step]:
    """Every capture of a camera-space set, in order, for a width x height projector; a
    ``mono`` camera's stages add each primary alone
    (:func:`~viewcomp.calib.io.patterns.primary_patterns`) after Table 1."""
    t1 = table1_patterns(width, height, CAMERA_COLOUR_LEVEL)
    geo = geometric_patterns(width, height)
    prim = primary_patterns(width, height) if mono else {}
    white = [Step("white", n, t1[n]) for n in TABLE1_ORDER]
    white += [Step("white", n, p) for n, p in prim.items()]
    white.append(Step("white", "chessboard", geo["chessboard"]))
    screen = [Step("screen", n, t1[n]) for n in TABLE1_ORDER]
    screen += [Step("screen", n, p) for n, p in prim.items()]
    screen += [Step("screen", n, p) for n, p in geo.items()]
    return _with_references(white, t1[REFERENCE]) + _with_references(screen, t1[REFERENCE])


def _with_references(steps: list[Step], reference: np.ndarray) -> list[Step]:
    """One stage's steps with the reference shown again every REFERENCE_EVERY captures after
    its first showing (not after a Gray-code plane whose inverse follows, nor last)."""
    out: list[Step] = []
    since: int | None = None  # captures since the reference was last shown
    for i, step in enumerate(steps):
        out.append(step)
        if step.name == REFERENCE:
            since = 0
            continue
        if since is None:
            continue
        since += 1
        if since >= REFERENCE_EVERY and i < len(steps) - 1 and not _opens_pair(step.name):
            out.append(Step(step.sub, reference_again(step.name), reference, check_only=True))
            since = 0
    return out


def _opens_pair(name: str) -> bool:
    """A Gray-code plane (graycode_00, _02, ...) whose inverse is the next capture."""
    digits = name.removeprefix("graycode_")
    return digits != name and digits.isdigit() and int(digits) % 2 == 0
