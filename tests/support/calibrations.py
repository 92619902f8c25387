"""Small real calibrations for tests and examples (simulated, a second or so)."""

from __future__ import annotations

from dataclasses import replace
from functools import lru_cache

from viewcomp.calib.fit.calibrate import Calibration, calibrate
from viewcomp.calib.io.captureset import capture_set_from_raw
from viewcomp.calib.sim.simulate import capture_patterns
from viewcomp.calib.sim.simulator import Simulator, make_screen, simulation_rig, white_screen


def small_simulator(w: int = 64, h: int = 32, seed: int = 0) -> Simulator:
    """The simulation rig at a small projector resolution."""
    rig = simulation_rig()
    rig = replace(rig, projector=replace(rig.projector, resolution=(w, h), principal_point=None))
    return Simulator(rig=rig, seed=seed)


@lru_cache(maxsize=8)
def small_calibration(
    w: int = 64, h: int = 32, screen: str = "magenta", gloss: str = "glossy", seed: int = 0
) -> Calibration:
    """A real Calibration (both methods) of a simulated screen on a w x h projector grid."""
    sim = small_simulator(w, h, seed)
    scr = make_screen(screen, gloss, shape=sim.shape, seed=seed)
    cs = capture_set_from_raw(
        sim.rig, capture_patterns(sim, white_screen()), capture_patterns(sim, scr)
    )
    return calibrate(cs)
