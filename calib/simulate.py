"""Simulated capture sets: what `viewcomp simulate` writes, and the evaluation's world.

The simulated world uses the example rig of INTERFACES.md with one change: the projector's
vertical field of view is 16 degrees instead of 20 (a slightly longer zoom). With it, the
mirror point of the projector seen from a viewer at 60 degrees (x = 0.134 m) lies at the
very edge of the image (half-width 0.14 m), so, as in the paper's experiment, the highlight
that dominates the view at 90 degrees "almost vanishes" at 60. At 20 degrees it stays well
inside the image and the two views differ much less (the evaluation report measures both).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from .capture import write_capture_set
from .patterns import table1_patterns
from .rig import Rig, default_rig
from .simulator import Screen, Simulator, make_screen, white_screen

SIM_PROJECTOR_FOV = 16.0
DEFAULT_SCREEN = "magenta"
DEFAULT_GLOSS = "glossy"


def simulation_rig() -> Rig:
    """The rig of the simulated world: INTERFACES.md's example with a 16-degree projector."""
    rig = default_rig()
    return replace(rig, projector=replace(rig.projector, fov_y=SIM_PROJECTOR_FOV))


def capture_patterns(sim: Simulator, screen: Screen, black: bool = True) -> dict[str, np.ndarray]:
    """The calibration camera's 8-bit captures of Table 1 (and black) on ``screen``."""
    w, h = sim.rig.projector.resolution
    pats = table1_patterns(w, h)
    names = ["red", "green", "blue", "gray", "ramp"] + (["black"] if black else [])
    return {k: sim.capture(screen, pats[k], f"{screen.name}/{k}") for k in names}


def simulate_capture_set(
    out_dir: str | Path,
    screen: str | tuple[float, float, float] = DEFAULT_SCREEN,
    gloss: str | tuple[float, float] = DEFAULT_GLOSS,
    space: str = "projector",
    seed: int = 0,
    rig: Rig | None = None,
    black: bool = True,
) -> list[Path]:
    """Write a capture set from the simulator (INTERFACES.md layout); returns the files.

    Raises:
        SimulatorError: an unknown screen or gloss.
        ValueError: an unsupported ``space``.
    """
    rig = rig or simulation_rig()
    if space != "projector":
        from .simcamera import simulate_camera_set  # camera space: lens, pose, Gray code

        return simulate_camera_set(out_dir, screen, gloss, seed=seed, rig=rig, black=black)
    sim = Simulator(rig=rig, seed=seed)
    scr = make_screen(screen, gloss, shape=sim.shape, seed=seed)
    white = capture_patterns(sim, white_screen(), black)
    real = capture_patterns(sim, scr, black)
    return write_capture_set(out_dir, rig, white, real)
