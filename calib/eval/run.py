"""``viewcomp evaluate``: run the protocols and write the report."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import numpy as np

from viewcomp.calib.eval.evaluate import (
    SWEEP_ANGLES,
    SWEEP_SCREENS,
    Progress,
    World,
    check_sweep,
    check_table2,
    gap_closed,
    sweep,
    sweep_adapted_means,
    sweep_means,
    table2,
)
from viewcomp.calib.eval.materials import MATERIAL_SIZE
from viewcomp.calib.eval.materials import materials as materials_protocol
from viewcomp.calib.eval.report import (
    write_audience_report,
    write_materials_report,
    write_report,
)

PROTOCOLS = ("table2", "sweep", "all", "materials", "audience", "hardware")
#: A tracked walk: times (n,) s, true eyes (n, 3) and tracked eyes (n, 3), metres.
Walk = tuple[np.ndarray, np.ndarray, np.ndarray]


def _finish(
    out_dir: str | Path,
    report: dict[str, Any],
    t0: float,
    write: Callable[[Path, dict[str, Any]], None],
) -> dict[str, Any]:
    """Stamp the run time (since ``t0``), write the report into ``out_dir``, return it."""
    report["seconds"] = round(time.perf_counter() - t0, 1)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    write(out, report)
    return report


def _run_materials(
    out_dir: str | Path,
    folder: str | Path | None,
    seed: int,
    size: tuple[int, int] | None,
    angles: Iterable[float],
    progress: Progress | None,
) -> dict[str, Any]:
    if folder is None:
        raise ValueError("the materials protocol needs the folder of measured materials")
    t0 = time.perf_counter()
    angles = [float(a) for a in angles]
    report: dict[str, Any] = {
        "config": {
            "protocol": "materials",
            "seed": seed,
            "projector": list(size or MATERIAL_SIZE),
            "angles": angles,
            "folder": str(folder),
        }
    }
    report |= materials_protocol(
        folder, seed=seed, size=size or MATERIAL_SIZE, angles=angles, progress=progress
    )
    return _finish(out_dir, report, t0, write_materials_report)


def _run_audience(
    out_dir: str | Path,
    seed: int,
    size: tuple[int, int] | None,
    screens: Iterable[str],
    walk: Walk | None,
    progress: Progress | None,
    space: str,
) -> dict[str, Any]:
    from viewcomp.calib.eval.audience import (
        JUDGE_VIEWERS,
        ZONES,
        walk_rows,
        zone_rows,
        zone_summary,
    )
    from viewcomp.calib.world.audience import ZONE_VIEWERS

    t0 = time.perf_counter()
    world = World.make(seed=seed, size=size, space=space)
    report: dict[str, Any] = {
        "config": {
            "protocol": "audience",
            "seed": seed,
            "capture_space": space,
            "projector": list(world.sim.rig.projector.resolution),
            "zones": [list(z) for z in ZONES],
            "audience_viewers": ZONE_VIEWERS,
            "judged_at": JUDGE_VIEWERS,
            "viewer": {
                "distance": world.sim.rig.viewer.distance,
                "height": world.sim.rig.viewer.height,
            },
        }
    }
    rows = zone_rows(world, screens=screens, progress=progress)
    report["zone_rows"] = rows
    report["zone_summary"] = zone_summary(rows)
    if walk is not None:
        report["walk"] = walk_rows(world, *walk, progress=progress)
    return _finish(out_dir, report, t0, write_audience_report)


def _run_hardware(
    out_dir: str | Path,
    folder: str | Path | None,
    seed: int,
    size: tuple[int, int] | None,
    progress: Progress | None,
) -> dict[str, Any]:
    from viewcomp.calib.eval.hardware import HARDWARE_SIZE, PROFILES, hardware
    from viewcomp.calib.eval.hwreport import write_hardware_report
    from viewcomp.calib.eval.materials import material_files

    t0 = time.perf_counter()
    screens: list[str | Path] = ["magenta"]
    if folder is not None:
        screens += material_files(folder)
    report: dict[str, Any] = {
        "config": {
            "protocol": "hardware",
            "seed": seed,
            "projector": list(size or HARDWARE_SIZE),
            "profiles": list(PROFILES),
            "screens": [str(s) for s in screens],
        }
    }
    report |= hardware(screens, size=size or HARDWARE_SIZE, seed=seed, progress=progress)
    return _finish(out_dir, report, t0, write_hardware_report)


def run(
    out_dir: str | Path,
    protocol: str = "all",
    seed: int = 0,
    size: tuple[int, int] | None = None,
    angles: Iterable[float] = SWEEP_ANGLES,
    screens: Iterable[str] = SWEEP_SCREENS,
    progress: Progress | None = None,
    space: str = "projector",
    materials: str | Path | None = None,
    walk: Walk | None = None,
) -> dict[str, Any]:
    """Run the protocol(s), write report.json, report.md and the plots; return the report.

    ``space = "camera"``: every calibration comes from simulated camera frames (lens, pose,
    chessboard and Gray code) rectified by `calibrate`, as with real hardware.
    ``protocol = "materials"``: the sweep on the measured materials in the folder
    ``materials`` (:mod:`viewcomp.calib.eval.materials`), at ``size`` (default 320x160).
    ``protocol = "hardware"``: the capture procedure on the hardware emulator's profiles
    (:mod:`viewcomp.calib.eval.hardware`) on the glossy magenta screen and the materials of
    ``materials`` (optional), beside ideal captures.
    ``protocol = "audience"``: the zone and walk of :mod:`viewcomp.calib.eval.audience` on
    ``screens``; ``walk``: the tracked walk (``viewcomp.rt.track.simtrack.tracked_walk``;
    None: the zone only).
    """
    if protocol not in PROTOCOLS:
        raise ValueError(f"protocol must be one of {', '.join(PROTOCOLS)}, got {protocol!r}")
    if protocol == "materials":
        return _run_materials(out_dir, materials, seed, size, angles, progress)
    if protocol == "audience":
        return _run_audience(out_dir, seed, size, screens, walk, progress, space)
    if protocol == "hardware":
        return _run_hardware(out_dir, materials, seed, size, progress)
    t0 = time.perf_counter()
    world = World.make(seed=seed, size=size, space=space)
    report: dict[str, Any] = {
        "config": {
            "seed": seed,
            "capture_space": space,
            "projector": list(world.sim.rig.projector.resolution),
            "projector_fov_y": world.sim.rig.projector.fov_y,
            "gloss": world.gloss,
            "lambda": world.lam,
            "tone_map_pixel_and_oracle": "smallest predicted colour error (CIE94)",
            "viewer": {
                "distance": world.sim.rig.viewer.distance,
                "height": world.sim.rig.viewer.height,
            },
        }
    }
    keep: dict[str, Any] = {}
    if protocol in ("table2", "all"):
        rows = table2(world, progress)
        report["table2"] = rows
        report["table2_checks"] = check_table2(rows)
        report["table2_gap_closed_sse"] = gap_closed(rows, "sse")
    if protocol in ("sweep", "all"):
        rows = sweep(world, screens, angles, progress=progress, keep=keep)
        report["sweep"] = rows
        means = sweep_means(rows)
        report["sweep_mean_de"] = means
        report["sweep_mean_adapted_de"] = sweep_adapted_means(rows)
        report["sweep_checks"] = check_sweep(means)
        report["sweep_gap_closed_de"] = gap_closed(rows, "de")
    return _finish(out_dir, report, t0, lambda out, rep: write_report(out, rep, world, keep))
