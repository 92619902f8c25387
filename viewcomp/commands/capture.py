"""`viewcomp capture OUT_DIR --camera N --monitor M`: a capture set from a real projector and
camera (or, with --simulate, from the simulated ones through the same procedure)."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from typing import TYPE_CHECKING

from viewcomp.calib.errors import UsageError

if TYPE_CHECKING:
    from viewcomp.calib.emu.emulator import Emulator
    from viewcomp.calib.emu.faults import Faults
    from viewcomp.calib.hw.clock import MonotonicClock
    from viewcomp.calib.hw.interface import Camera, Clock, Projector
    from viewcomp.calib.hw.simrig import SimulatedRig
    from viewcomp.calib.world.rig import Rig


def register(sub: argparse._SubParsersAction) -> None:
    from viewcomp.commands._common import add_force_argument

    p = sub.add_parser(
        "capture",
        help="drive a projector and a camera and write a capture set",
        description="Show every calibration pattern fullscreen on the projector's monitor, "
        "grab and average camera frames (exposure and white balance locked where the camera "
        "allows), check each capture at once (saturated, too dark, not visible, camera moved, "
        "chessboard not found) and say what to change. Asks you to put the white screen in "
        "place for white/ and the real screen for screen/. Writes a capture set with "
        '[capture] space = "camera" and a rig.toml to complete; nothing is written when a '
        "capture is refused.",
    )
    p.add_argument("out_dir", nargs="?", help="capture-set folder to write (new or empty)")
    _add_device_arguments(p)
    _add_capture_arguments(p)
    p.add_argument(
        "--rig",
        default=None,
        help="a rig.toml whose geometry to keep (resolutions are measured); without it the "
        "written rig.toml must be completed by hand",
    )
    p.add_argument(
        "--response",
        default=None,
        help='camera response to write into rig.toml: "estimate" (from the Gray-code '
        'captures; the default without --rig), "srgb", "linear" or a gamma g',
    )
    p.add_argument("--yes", action="store_true", help="answer every prompt (unattended runs)")
    p.add_argument(
        "--list-monitors", action="store_true", help="list the monitors GLFW sees and exit"
    )
    _add_simulation_arguments(p)
    _add_emulation_arguments(p)
    add_force_argument(p, "capture set")
    p.set_defaults(run=run)


def _add_device_arguments(p: argparse.ArgumentParser) -> None:
    """--camera, --camera-backend and --monitor: which devices to drive."""
    p.add_argument(
        "--camera",
        default=None,
        help="the camera, as the backend names it: an OpenCV index (0 is the first), a gphoto2 "
        "model or port, PRODUCER.cti[#SERIAL] for genicam, anything for a plug-in",
    )
    p.add_argument(
        "--camera-backend",
        default="opencv",
        help="opencv (default), gphoto2 (DSLRs; pip install gphoto2), genicam (machine vision "
        "through a GenTL producer; pip install harvesters), or module:factory, a plug-in: "
        "factory(spec) -> Camera in an importable module, called with --camera",
    )
    p.add_argument("--monitor", type=int, help="the projector's monitor (see --list-monitors)")


def _add_capture_arguments(p: argparse.ArgumentParser) -> None:
    """How each capture is taken: frames, settling, exposure, retries, automatic modes, HDR
    and the camera's resolution."""
    p.add_argument(
        "--frames",
        type=int,
        default=None,
        help="frames averaged per capture (default 16 for a camera that delivers 8-bit frames, "
        "whose codes and codec only the sensor's noise dithers; 8 for deeper ones)",
    )
    p.add_argument(
        "--settle",
        type=float,
        default=None,
        help="seconds added to the measured projector->camera latency before a frame counts "
        "as showing its pattern (default 0.1; 0 with --simulate)",
    )
    p.add_argument(
        "--exposure",
        type=float,
        default=None,
        help="camera exposure in seconds (with --simulate: 1 s is the simulator's unit "
        "exposure); with --hdr the bracket's base (relative exposure 1). Default: searched "
        "with the white screen up, so that the brightest pattern's lit region reaches 80%% of "
        "full scale",
    )
    p.add_argument(
        "--retries",
        type=int,
        default=3,
        help="failed camera reads retried in a row before the camera counts as gone (default 3)",
    )
    p.add_argument(
        "--allow-auto",
        action="store_true",
        help="go on (with a warning) when the camera's automatic exposure or white balance "
        "cannot be switched off; without it that is an error",
    )
    p.add_argument(
        "--hdr",
        action="store_true",
        help="bracket every capture in whole projector refresh periods (relative exposures 1, "
        "1/4, 1/16, 1/64, 1/256 of the camera's exposure, as far as whole periods go; when "
        "fewer than two fit, upward: one period at gain 1, then 4 and 16 times it) and merge "
        "the frames into float32 linear .npy captures; needs a camera whose exposure can be "
        "set",
    )
    p.add_argument(
        "--camera-size", default=None, help="camera resolution WIDTHxHEIGHT to ask the driver for"
    )


def _add_simulation_arguments(p: argparse.ArgumentParser) -> None:
    """--simulate and the simulator's options (the simulated projector and camera)."""
    from viewcomp.commands._common import add_simulator_arguments

    sim = p.add_argument_group("simulation (no hardware)")
    sim.add_argument(
        "--simulate",
        action="store_true",
        help="use the simulated projector and camera instead of --camera and --monitor",
    )
    add_simulator_arguments(sim, size="--sim-size", material=True)


def _add_emulation_arguments(p: argparse.ArgumentParser) -> None:
    """--emulate and its injected faults (the emulated projector and camera)."""
    emu = p.add_argument_group("hardware emulation (no hardware, harsher than --simulate)")
    emu.add_argument(
        "--emulate",
        choices=("webcam", "dslr", "mono12"),
        default=None,
        help="run the real procedure on emulated devices: a DLP projector (latency 2-4 "
        "refreshes, colour sub-frames) and a camera profile (webcam: 1280x720-like UVC with "
        "MJPEG, driver queue, auto exposure, rolling shutter; dslr: slow raw 14-bit; mono12: "
        "machine vision); the screen from --screen/--gloss or --material, the projector's "
        "size from --sim-size, the randomness from --seed",
    )
    emu.add_argument(
        "--bump-at",
        metavar="K:PX",
        default=None,
        help="with --emulate: bump the camera at the K-th pattern shown (counted from 0, the "
        "latency sentinel included) so the image moves about PX camera pixels",
    )
    emu.add_argument(
        "--faults",
        metavar="SPEC",
        default=None,
        help="with --emulate: more faults, comma-separated: drop=G+G (lost frames at grabs G, "
        "counted from 0), fail=G+G (failed reads), late=K+K (patterns lit one refresh late), "
        "drop_p=P, fail_p=P, late_p=P (probabilities)",
    )


def run(args: argparse.Namespace) -> int:
    from viewcomp.commands._common import Log

    if args.list_monitors:
        return _list_monitors()
    if args.out_dir is None:
        raise UsageError("give the capture-set folder OUT_DIR")
    _check_out_dir(args)
    _check_numbers(args)
    faults = _emulator_faults(args)
    if not (args.simulate or args.emulate) and (
        (args.camera is None and args.camera_backend == "opencv") or args.monitor is None
    ):
        raise UsageError(
            "give --camera N and --monitor M (or --simulate or --emulate for no hardware)"
        )
    from viewcomp.calib.hw.procedure import NO_TERMINAL, run_capture
    from viewcomp.calib.io.hdr import DEFAULT_STOPS
    from viewcomp.calib.world.rig import load_rig

    template = load_rig(args.rig) if args.rig else None
    response = _response(args, template)
    if not args.yes and not _interactive():  # checked last: the other mistakes come first
        raise UsageError(NO_TERMINAL.format(why="is not a terminal"))
    log = Log()
    base_prompt = (lambda stage, message: _auto(stage, message, log)) if args.yes else None
    projector, camera, clock, prompt, settle, template = _devices(
        args, template, faults, base_prompt
    )
    try:
        paths = run_capture(
            args.out_dir,
            projector,
            camera,
            rig_template=template,
            prompt=prompt,
            log=log,
            frames=args.frames,
            settle=settle,
            clock=clock,
            response=response,
            hdr_stops=DEFAULT_STOPS if args.hdr else None,
            exposure=_exposure(args),
            allow_auto=args.allow_auto,
            retries=args.retries,
        )
    finally:
        projector.close()
        camera.close()
        if args.emulate:
            print(f"emulated devices' clock: {clock.now():.1f} s", file=sys.stderr)
    print(f"wrote a camera-space capture set ({len(paths)} files) to {args.out_dir}")
    return 0


def _check_numbers(args: argparse.Namespace) -> None:
    """--retries, --frames and --settle in their ranges."""
    if args.retries < 0:
        raise UsageError(f"--retries must be >= 0, got {args.retries}")
    if args.frames is not None and args.frames < 1:
        raise UsageError(f"--frames must be at least 1, got {args.frames}")
    if args.settle is not None and args.settle < 0:
        raise UsageError(f"--settle is seconds >= 0, got {args.settle}")


def _response(args: argparse.Namespace, template: Rig | None) -> str | None:
    """The camera response to write: --response, checked; without it "estimate" on hardware
    without --rig (with --hdr: from a bracket (Debevec), else from the Gray code), else None
    (the template's)."""
    response = args.response
    if response is None and template is None and not (args.simulate or args.emulate):
        response = "estimate"  # with --hdr: from a bracket (Debevec), else from the Gray code
    if response is not None and response != "estimate":
        from viewcomp.calib.world.response import parse_response

        try:
            parse_response(response)
        except ValueError as e:
            raise UsageError(f"--response: {e}") from None
    return response


def _devices(
    args: argparse.Namespace,
    template: Rig | None,
    faults: Faults | None,
    base_prompt: Callable[[str, str], bool] | None,
) -> tuple[Projector, Camera, Clock, Callable[[str, str], bool], float, Rig | None]:
    """The projector, camera and clock to capture with (simulated, emulated or hardware),
    the prompt (``base_prompt``, else the console's; the simulated and emulated hands then
    swap the screen), the settling time (s) and the rig template (the simulated and emulated
    rigs' own geometry)."""
    from viewcomp.calib.hw.procedure import console_prompt
    from viewcomp.commands._common import parse_size

    if args.simulate:
        size = parse_size(args.sim_size) if args.sim_size else None
        rig_dev, projector, camera, template = _simulated(args, size, template)

        def prompt(stage: str, message: str) -> bool:
            ok = (base_prompt or console_prompt)(stage, message)
            if ok:
                rig_dev.use_screen(stage)  # the simulated hands swap the screen
            return ok

        settle = 0.0 if args.settle is None else args.settle
        clock = rig_dev.clock
    elif args.emulate:
        size = parse_size(args.sim_size) if args.sim_size else None
        emulator, template = _emulated(args, size, template, faults)
        projector, camera, clock = emulator.projector, emulator.camera, emulator.clock

        def prompt(stage: str, message: str) -> bool:
            ok = (base_prompt or console_prompt)(stage, message)
            if ok:
                emulator.swap_screen(stage)  # the emulated hands swap the screen
            return ok

        settle = 0.1 if args.settle is None else args.settle
    else:
        from viewcomp.calib.hw.clock import MonotonicClock

        clock = MonotonicClock()
        projector, camera = _hardware(args, parse_size, clock)
        prompt = base_prompt or console_prompt
        settle = 0.1 if args.settle is None else args.settle
    return projector, camera, clock, prompt, settle, template


def _exposure(args: argparse.Namespace) -> float | str | None:
    """What run_capture is told: "auto" (search) without --exposure; the seconds given on
    hardware; None with --simulate (the simulated camera starts at --exposure)."""
    if args.exposure is None:
        return "auto"
    return None if args.simulate else float(args.exposure)


def _interactive() -> bool:
    """True when standard input is a terminal (someone can answer the prompts)."""
    try:
        return sys.stdin is not None and sys.stdin.isatty()
    except (AttributeError, ValueError, OSError):
        return False


def _auto(stage: str, message: str, log: Callable[[str], None]) -> bool:
    log(f"[{stage}] {message} (--yes: continuing)")
    return True


def _simulated(
    args: argparse.Namespace, size: tuple[int, int] | None, template: Rig | None
) -> tuple[SimulatedRig, Projector, Camera, Rig]:
    """The simulated rig (screens "white" and "screen"), its two devices, and the rig.toml to
    write (the simulation's geometry, without the lens)."""
    from dataclasses import replace

    from viewcomp.calib.hw.simrig import SimulatedRig as _SimulatedRig
    from viewcomp.calib.sim.simcamera import camera_simulator, scaled_camera_rig, written_rig
    from viewcomp.calib.sim.simulator import (
        PROJECTOR_PRESETS,
        AnyScreen,
        make_screen,
        material_screen,
        simulation_rig,
        white_screen,
    )
    from viewcomp.commands._common import simulated_screen

    colour, gloss, material, projector = simulated_screen(args)
    rig = template or simulation_rig()
    if size is not None:
        rig = replace(rig, projector=replace(rig.projector, resolution=size, principal_point=None))
    true_rig = scaled_camera_rig(rig, size)
    if args.exposure is not None and not args.exposure > 0:
        raise UsageError(f"--exposure is seconds > 0, got {args.exposure}")
    sim = camera_simulator(true_rig, args.seed, PROJECTOR_PRESETS[projector], args.exposure)
    screen: AnyScreen
    if material is not None:
        screen = material_screen(material)
    else:
        screen = make_screen(colour, gloss, shape=sim.shape, seed=args.seed)
    dev = _SimulatedRig(sim, {"white": white_screen(), "screen": screen})
    # the simulated world's geometry is known: write it (without the lens, for calibrate)
    return dev, dev.projector, dev.camera, written_rig(true_rig)


def _emulator_faults(args: argparse.Namespace) -> Faults | None:
    """The faults of --bump-at and --faults (None without --emulate, where they are refused)."""
    if not args.emulate:
        for flag, value in (("--bump-at", args.bump_at), ("--faults", args.faults)):
            if value is not None:
                raise UsageError(f"{flag} injects a fault into emulated devices: add --emulate")
        return None
    if args.simulate:
        raise UsageError("--simulate and --emulate are two different rigs: give one")
    from dataclasses import replace

    from viewcomp.calib.emu.faults import Faults, FaultSpecError, parse_bump, parse_faults

    try:
        faults = parse_faults(args.faults) if args.faults else Faults()
        if args.bump_at is not None:
            faults = replace(faults, bump_at=parse_bump(args.bump_at))
    except FaultSpecError as e:
        flag = "--faults" if args.bump_at is None or "bump" not in str(e) else "--bump-at"
        raise UsageError(f"{flag}: {e}") from None
    return faults


def _emulated(
    args: argparse.Namespace,
    size: tuple[int, int] | None,
    template: Rig | None,
    faults: Faults | None,
) -> tuple[Emulator, Rig]:
    """The emulated rig (:func:`viewcomp.calib.emu.emulator.open_emulator`) and the rig.toml
    to write: the true geometry without the lens, with the response the camera's spec sheet
    would give (linear raw, or sRGB for a webcam: not its true tone curve)."""
    from dataclasses import replace

    from viewcomp.calib.emu.emulator import open_emulator
    from viewcomp.calib.sim.simcamera import written_rig
    from viewcomp.calib.sim.simulator import simulation_rig
    from viewcomp.commands._common import simulated_screen

    colour, gloss, material, _ = simulated_screen(args)
    rig = template or simulation_rig()
    emu = open_emulator(
        args.emulate,
        material if material is not None else colour,
        seed=args.seed,
        projector_size=size or rig.projector.resolution,
        gloss=gloss,
        faults=faults,
        rig=rig,
    )
    written = written_rig(emu.truth.rig)
    response = "linear" if emu.profile.linear else "srgb"
    return emu, replace(written, camera=replace(written.camera, response=response))


def _hardware(
    args: argparse.Namespace,
    parse_size: Callable[[str], tuple[int, int]],
    clock: MonotonicClock,
) -> tuple[Projector, Camera]:
    """The glfw projector on --monitor and the camera --camera of --camera-backend, on
    ``clock``."""
    from viewcomp.calib.hw.backends import open_camera
    from viewcomp.rt.play.projector import GlfwProjector

    if args.exposure is not None and not args.exposure > 0:
        raise UsageError(f"--exposure is seconds > 0, got {args.exposure}")
    cam_size = parse_size(args.camera_size) if args.camera_size else None
    camera = open_camera(args.camera_backend, args.camera or "", clock, cam_size)
    units = getattr(camera, "units", None)
    if units:
        print(f"{camera.name}: exposure {units}", file=sys.stderr)
    try:
        projector = GlfwProjector(args.monitor, clock=clock)
    except BaseException:
        camera.close()
        raise
    return projector, camera


def _list_monitors() -> int:
    from viewcomp.rt.play.projector import list_monitors

    mons = list_monitors()
    if not mons:
        print("GLFW sees no monitor", file=sys.stderr)
        return 1
    for m in mons:
        print(m)
    return 0


def _check_out_dir(args: argparse.Namespace) -> None:
    """OUT_DIR new or empty (an old capture set only with --force), never an input."""
    from viewcomp.commands._common import check_output_folder

    check_output_folder(args.out_dir, args.rig, force=args.force, what="capture set")
