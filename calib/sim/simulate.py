"""Simulated capture sets: what `viewcomp simulate` writes (projector or camera space).

A set shows an analytic screen (a colour and a gloss) or a measured material (a ``.npz`` of
:mod:`~viewcomp.calib.sim.materials`, with the DLP-like projector by default), with the white
screen as the matte reference, in 8 bits or HDR (bracketed and merged: float32 linear
``.npy``). The camera's exposure may be chosen from the scene (:func:`auto_exposure`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import replace
from os import PathLike
from pathlib import Path

import numpy as np

from viewcomp.calib.io.captureset import write_capture_set
from viewcomp.calib.io.patterns import table1_patterns
from viewcomp.calib.sim.materials import Material
from viewcomp.calib.sim.simcamera import (
    SimCamera,
    camera_patterns,
    camera_rig,
    camera_simulator,
    simulate_camera_set,
)
from viewcomp.calib.sim.simulator import (
    DLP_PROJECTOR,
    AnyScreen,
    CameraPhysics,
    ProjectorPhysics,
    Simulator,
    SimulatorError,
    make_screen,
    material_screen,
    simulation_rig,
    white_screen,
)
from viewcomp.calib.world.rig import Rig

DEFAULT_SCREEN = "magenta"
DEFAULT_GLOSS = "glossy"

#: Largest linear camera value (of full scale) that ``exposure="auto"`` lets an 8-bit capture
#: reach, noise-free: the 2% left over is far above the noise (read 0.002 of full scale).
EXPOSURE_LIMIT = 0.98
#: Where ``exposure="auto"`` puts the white screen's gray capture (median over the lit
#: pixels, of full scale) for HDR captures: the diffuse level well exposed; the bracket's
#: shorter frames hold the highlights.
HDR_GRAY_LEVEL = 0.5

TABLE1_CAPTURES = ("red", "green", "blue", "gray", "ramp")


def capture_patterns(
    sim: Simulator, screen: AnyScreen, black: bool = True
) -> dict[str, np.ndarray]:
    """The calibration camera's captures of Table 1 (and black) on ``screen``: 8-bit codes, or
    float32 linear when the camera brackets exposures (``CameraPhysics.hdr_stops``)."""
    pats = projector_patterns(sim.rig.projector.resolution, black)
    return {k: sim.capture(screen, img, f"{screen.name}/{k}") for k, img in pats.items()}


def projector_patterns(size: tuple[int, int], black: bool = True) -> dict[str, np.ndarray]:
    """The patterns of a projector-space set, for a projector of ``size`` (W, H): Table 1 (and
    black), name -> (H, W, 3) uint8."""
    pats = table1_patterns(*size)
    names = [*TABLE1_CAPTURES, *(["black"] if black else [])]
    return {k: pats[k] for k in names}


def auto_exposure(
    linear: Callable[[AnyScreen, np.ndarray], np.ndarray],
    captures: Iterable[tuple[AnyScreen, np.ndarray]],
    hdr: bool,
    lit: np.ndarray | None = None,
) -> float:
    """The camera exposure chosen from the scene.

    Args:
        linear: the camera's noise-free linear signal at exposure 1 for (screen, pattern):
            (H, W, 3), vignetting and optics included.
        captures: every (screen, pattern) the set captures; for ``hdr``, the first must be the
            white screen's gray.
        hdr: False: the largest exposure at which no capture exceeds :data:`EXPOSURE_LIMIT` of
            full scale (an 8-bit set with nothing clipped); True: the exposure that puts the
            white screen's gray at :data:`HDR_GRAY_LEVEL` (median over ``lit``).
        lit: (H, W) bool, the pixels the projector lights (None: all).

    Returns:
        the exposure, > 0.

    Raises:
        SimulatorError: the scene is black (no light to expose for).
    """
    if hdr:
        screen, pattern = next(iter(captures))
        gray = linear(screen, pattern)
        level = float(np.median(gray if lit is None else gray[lit]))
        if not level > 0:
            raise SimulatorError("the white screen's gray capture is black: nothing to expose for")
        return HDR_GRAY_LEVEL / level
    peak = max(float(np.max(linear(screen, pattern))) for screen, pattern in captures)
    if not peak > 0:
        raise SimulatorError("every capture is black: nothing to expose for")
    return EXPOSURE_LIMIT / peak


def simulate_capture_set(
    out_dir: str | Path,
    screen: str | tuple[float, float, float] = DEFAULT_SCREEN,
    gloss: str | tuple[float, float] = DEFAULT_GLOSS,
    space: str = "projector",
    seed: int = 0,
    rig: Rig | None = None,
    black: bool = True,
    *,
    material: str | PathLike[str] | Material | None = None,
    projector: ProjectorPhysics | None = None,
    exposure: float | str | None = None,
    hdr_stops: tuple[float, ...] | None = None,
    log: Callable[[str], None] | None = None,
) -> list[Path]:
    """Write a capture set from the simulator (docs/INTERFACES.md layout); returns the files.

    Args:
        out_dir: the capture-set folder (new, or an earlier capture set).
        screen, gloss: the analytic screen (:func:`make_screen`); ignored with ``material``.
        space: ``"projector"`` (captures on the projector grid) or ``"camera"`` (raw camera
            frames, lens and all: :func:`simulate_camera_set`).
        seed: the noise seed. rig: the world (default :func:`simulation_rig`).
        black: write the optional black captures.
        material: a measured material (its ``.npz`` path, or a :class:`Material`) as the
            screen (:func:`material_screen`, the default lens).
        projector: the projector's physics; None: :data:`DLP_PROJECTOR` with ``material``,
            :class:`ProjectorPhysics` otherwise.
        exposure: the camera's exposure: a number > 0, ``"auto"`` (:func:`auto_exposure`,
            8-bit: nothing clips; HDR: the white gray at :data:`HDR_GRAY_LEVEL`), or None
            (``"auto"`` for HDR, the :class:`CameraPhysics` default for 8-bit).
        hdr_stops: None for 8-bit PNG captures; relative exposures of an HDR bracket (e.g.
            :data:`~viewcomp.calib.io.hdr.DEFAULT_STOPS`) for float32 linear ``.npy`` captures.
        log: receives one line naming the exposure ``"auto"`` chose.

    Raises:
        SimulatorError: an unknown screen or gloss, a bad exposure or bracket.
        MaterialError: a material file that cannot be used.
        ValueError: an unsupported ``space``.
    """
    if space not in ("projector", "camera"):
        raise ValueError(f'space must be "projector" or "camera", got {space!r}')
    if isinstance(exposure, str) and exposure != "auto":
        raise SimulatorError(f'exposure is a number > 0 or "auto", got {exposure!r}')
    rig = rig or simulation_rig()
    proj = projector or (DLP_PROJECTOR if material is not None else ProjectorPhysics())
    camera = CameraPhysics(hdr_stops=hdr_stops)
    if space == "camera":
        cam = SimCamera(camera_simulator(camera_rig(rig), seed, proj, hdr_stops=hdr_stops))
        sim = cam.sim
    else:
        sim = Simulator(rig=rig, seed=seed, projector=proj, camera=camera)
    if material is not None:
        scr: AnyScreen = material_screen(material)
    else:
        scr = make_screen(screen, gloss, shape=sim.shape, seed=seed)
    if exposure is None and hdr_stops is not None:
        exposure = "auto"
    if exposure == "auto":
        exposure = choose_exposure(sim, cam if space == "camera" else None, scr, black, hdr_stops)
        if log is not None:
            kind = "HDR: the white gray at" if hdr_stops else "8-bit: nothing above"
            level = HDR_GRAY_LEVEL if hdr_stops else EXPOSURE_LIMIT
            log(f"exposure auto: {exposure:.4g} ({kind} {level:g} of full scale)")
    if space == "camera":
        return simulate_camera_set(
            out_dir,
            scr,
            seed=seed,
            rig=rig,
            black=black,
            projector=proj,
            exposure=None if exposure is None else float(exposure),  # "auto" is resolved
            hdr_stops=hdr_stops,
        )
    if exposure is not None:
        sim = replace(sim, camera=replace(sim.camera, exposure=float(exposure)))
    white = capture_patterns(sim, white_screen(), black)
    real = capture_patterns(sim, scr, black)
    return write_capture_set(out_dir, rig, white, real)


def choose_exposure(
    sim: Simulator,
    cam: SimCamera | None,
    screen: AnyScreen,
    black: bool,
    hdr_stops: tuple[float, ...] | None,
) -> float:
    """The exposure ``exposure="auto"`` chooses: :func:`auto_exposure` over every capture of
    the white screen and ``screen`` that :func:`simulate_capture_set` writes with ``sim``
    (``cam``, its camera, in camera space; None in projector space); HDR when ``hdr_stops``
    is not None."""
    white = white_screen()
    scale = 1.0 / sim.camera.exposure
    if cam is not None:
        size = sim.rig.projector.resolution
        todo: list[tuple[AnyScreen, np.ndarray]] = [
            (white, p) for p in camera_patterns(size, black, "chessboard").values()
        ]
        todo += [(screen, p) for p in camera_patterns(size, black, "all").values()]
        todo.insert(0, (white, camera_patterns(size, False, "none")["gray"]))
        return auto_exposure(
            lambda s, p: cam.linear(s, p) * scale, todo, hdr_stops is not None, cam.view.inside
        )
    pats = projector_patterns(sim.rig.projector.resolution, black)
    todo = [(white, pats["gray"])]
    todo += [(s, p) for s in (white, screen) for p in pats.values()]
    eye = sim.geometry.camera
    return auto_exposure(
        lambda s, p: sim.expose(sim.radiance(s, p, eye), vignetting=True) * scale,
        todo,
        hdr_stops is not None,
    )
