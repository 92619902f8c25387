"""Simulated capture sets: what `viewcomp simulate` writes (projector or camera space)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from viewcomp.calib.io.captureset import write_capture_set
from viewcomp.calib.io.patterns import table1_patterns
from viewcomp.calib.sim.simcamera import simulate_camera_set
from viewcomp.calib.sim.simulator import (
    Screen,
    Simulator,
    make_screen,
    simulation_rig,
    white_screen,
)
from viewcomp.calib.world.rig import Rig

DEFAULT_SCREEN = "magenta"
DEFAULT_GLOSS = "glossy"


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
    """Write a capture set from the simulator (docs/INTERFACES.md layout); returns the files.

    Raises:
        SimulatorError: an unknown screen or gloss.
        ValueError: an unsupported ``space``.
    """
    rig = rig or simulation_rig()
    if space != "projector":
        return simulate_camera_set(out_dir, screen, gloss, seed=seed, rig=rig, black=black)
    sim = Simulator(rig=rig, seed=seed)
    scr = make_screen(screen, gloss, shape=sim.shape, seed=seed)
    white = capture_patterns(sim, white_screen(), black)
    real = capture_patterns(sim, scr, black)
    return write_capture_set(out_dir, rig, white, real)
