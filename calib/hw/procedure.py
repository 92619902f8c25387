"""The capture procedure of `viewcomp capture`: patterns in, a checked capture set out.

The devices are those of :mod:`viewcomp.calib.hw.interface`. Before the first capture the
camera's automatic modes are locked (:mod:`~viewcomp.calib.hw.camlock`) and the projector ->
camera latency is measured (:mod:`~viewcomp.calib.hw.latency`). Then for each pattern, in
order: show it on the projector (its swap time t), average ``frames`` camera frames whose
exposure started at or after t + latency + ``settle`` (:class:`~viewcomp.calib.hw.reader.
FrameReader`: the driver's queue is drained by timestamps, failed reads retried), and check
the capture at once, so that a problem is named while the user can still fix it:

- saturated: more than 0.5% of the lit pixel-channels at the maximum code -> lower the
  exposure (or the projector's brightness);
- too dark / pattern not visible: the projected image does not stand out from black -> check
  the monitor, the camera's aim, the exposure;
- wrong pattern: red, green, blue must raise their own camera channel most over gray;
- camera moved: the projector frame's edges (highlights and clipped pixels left out,
  :mod:`viewcomp.calib.geo.framematch`) lie more than 1 camera pixel from where the latest
  showing of the stage's gray has them, gray shown again (every few captures, see
  :mod:`viewcomp.calib.hw.plan`; not written) lies more than that from the stage's first,
  or the chessboard corners from the white stage's;
- chessboard not found.

The sets: ``white/`` on the ideal matte white screen (Table 1, black, chessboard), after a
prompt to put it in place; then ``screen/`` on the real screen (the same, plus the Gray code
of OpenCV structured_light). Each stage ends with gray once more, compared with its first
(the camera moved during the stage). Before anything is written, the whole set goes
through the geometric calibration that `viewcomp calibrate` will run
(:func:`viewcomp.calib.geo.rectify.rectify_capture_set`) and its saturation and darkness checks:
a set that is written calibrates. A refused capture raises
:class:`~viewcomp.calib.io.imageio.CaptureError` (or ``FitError``) and nothing is written.

With an HDR bracket (``hdr_stops``, `capture --hdr`), each capture is the camera's frames at
every relative exposure (:class:`~viewcomp.calib.hw.bracket.Bracket`, whole projector refresh
periods), merged into float32 linear light as it is taken;
"saturated" then means clipped even in the shortest exposure, and the set is written as
``.npy``.

Prompts go through a callable ``prompt(stage, message) -> bool`` (False: stop), so tests
and unattended runs (``--yes``) answer them.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

from viewcomp.calib.hw.camlock import lock_controls
from viewcomp.calib.hw.clock import MonotonicClock
from viewcomp.calib.hw.interface import Camera, Clock, Projector
from viewcomp.calib.hw.livechecks import LiveChecks
from viewcomp.calib.hw.mono import MONO_LIMITS
from viewcomp.calib.hw.monochecks import MonoChecks
from viewcomp.calib.hw.plan import Step, capture_plan
from viewcomp.calib.hw.progress import Progress
from viewcomp.calib.hw.reader import FrameReader
from viewcomp.calib.hw.session import Session
from viewcomp.calib.io.atomic import atomic_open
from viewcomp.calib.io.captureset import (
    RIG_FILE,
    CaptureSet,
    capture_set_from_raw,
    write_capture_set,
)
from viewcomp.calib.io.checks import check_captures
from viewcomp.calib.io.imageio import CaptureError
from viewcomp.calib.world.response import parse_response
from viewcomp.calib.world.rig import CaptureSpec, Rig, default_rig, rig_to_toml
from viewcomp.calib.world.tracker import with_default_tracker

Prompt = Callable[[str, str], bool]
Log = Callable[[str], None]


STAGE_MESSAGES = {
    "white": (
        "Put the ideal matte white screen (a white board) exactly where the screen will be, "
        "darken the room, and fix the camera: it must not move until the capture is done."
    ),
    "screen": (
        "Now replace the white screen by the real screen, in exactly the same place. Do not "
        "move the camera or the projector."
    ),
}

COMPLETE_HEADER = """\
# TO COMPLETE: `viewcomp capture` measured the resolutions only. Measure and enter the
# projector's and the camera's position, look_at and fov_y (metres, degrees; the world frame of
# docs/MODEL.md of viewcomp: the screen is z = 0, +y up, +z toward the audience) and the
# camera's response, then run `viewcomp calibrate`. The lens distortion is estimated by
# calibrate. [tracker] is a guess too (a 90-degree 720p webcam on the picture's top edge):
# measure the webcam that follows the audience (docs/INTERFACES.md, rig.toml) before
# `viewcomp track` or `viewcomp play --track-camera`, or give it there with --tracker.
"""


def capture_rig(
    template: Rig | None, projector: tuple[int, int], camera: tuple[int, int]
) -> tuple[Rig, bool]:
    """The rig.toml of the new set: the template's (or the example rig's) geometry with the
    devices' resolutions and ``space = "camera"``. Returns it and whether the user must still
    complete it (no template given). A template without ``[tracker]`` gets the default
    webcam on the picture's top edge (:func:`viewcomp.calib.world.tracker.default_tracker`),
    to be measured and corrected for the kiosk's own."""
    base = with_default_tracker(template if template is not None else default_rig())
    rig = replace(
        base,
        projector=replace(base.projector, resolution=projector, principal_point=None)
        if base.projector.resolution != projector
        else base.projector,
        camera=replace(base.camera, resolution=camera, principal_point=None)
        if base.camera.resolution != camera
        else base.camera,
        capture=CaptureSpec(space="camera"),
    )
    return rig, template is None


def _check_writable(out: Path) -> None:
    if out.exists() and not out.is_dir():
        raise CaptureError(f"cannot write a capture set to {out}: it is a file, not a folder")
    if out.is_dir() and any(out.iterdir()) and not (out / RIG_FILE).is_file():
        raise CaptureError(
            f"refusing to write a capture set into {out}: the folder is not empty and has no "
            f"{RIG_FILE} - choose a new or empty folder"
        )


NO_TERMINAL = (
    "capture asks you to put each screen up and confirm, and standard input {why}: run it "
    "in a terminal, or pass --yes for an unattended run; nothing was written"
)


def console_prompt(stage: str, message: str) -> bool:
    """Ask on the terminal: Enter continues, q stops (False).

    Raises:
        CaptureError: no answer can come (standard input ended or is not readable).
    """
    print(f"\n[{stage}] {message}", flush=True)
    try:
        answer = input("Press Enter when ready (q to quit): ")
    except (EOFError, OSError):
        print(flush=True)
        raise CaptureError(NO_TERMINAL.format(why="ended before an answer")) from None
    return answer.strip().lower() not in ("q", "quit")


def run_capture(
    out_dir: str | Path,
    projector: Projector,
    camera: Camera,
    rig_template: Rig | None = None,
    prompt: Prompt = console_prompt,
    log: Log = print,
    frames: int | None = None,
    settle: float = 0.0,
    clock: Clock | None = None,
    response: str | float | None = None,
    hdr_stops: tuple[float, ...] | None = None,
    exposure: float | str | None = None,
    allow_auto: bool = False,
    retries: int = 3,
) -> list[Path]:
    """Capture a camera-space set into ``out_dir`` (see the module doc); returns the files.

    Args:
        out_dir: a new or empty folder, or an old capture set (its files are replaced).
        projector, camera: the devices (:mod:`viewcomp.calib.hw.interface`).
        rig_template: rig.toml geometry to keep (its resolutions are replaced by the
            devices'); None: the example rig, written with a "to complete" note.
        prompt: asks the user to swap screens; returning False stops (nothing written).
        log: progress and warnings.
        frames: frames averaged per capture (>= 1; None: :func:`.frames.default_frames`).
        settle: seconds added to the measured latency before a frame counts as showing the
            pattern (a projector whose light settles slowly: dynamic iris, lamp).
        clock: the devices' clock (None: :class:`~viewcomp.calib.hw.clock.MonotonicClock`).
        response: the camera's response to write: None keeps the template's (sRGB without
            one), ``"estimate"`` estimates it from the Gray-code captures (light adds up:
            :func:`viewcomp.calib.geo.camresponse.estimate_response`), otherwise a rig.toml value.
        hdr_stops: None for one exposure per capture (encoded codes, written as PNG); or the
            relative exposures of an HDR bracket (:class:`~viewcomp.calib.hw.bracket.Bracket`,
            whole projector refresh periods): every capture is taken at each and merged,
            written as float32 linear ``.npy``. Needs a camera whose exposure can be set;
            with ``response="estimate"`` the response is estimated from a bracket of the ramp
            (OpenCV's Debevec) before the captures.
        exposure: the camera's exposure in seconds; ``"auto"`` searches it
            (:mod:`~viewcomp.calib.hw.autoexposure`) with the white screen up; None keeps
            the camera's.
        allow_auto: go on (with a warning) when the camera's automatic exposure or white
            balance cannot be switched off; otherwise that is an error.
        retries: failed reads retried in a row before the camera counts as gone.

    Raises:
        CaptureError: a capture is refused (the message names it and the fix), the user
            stopped, or the folder cannot hold a capture set. Nothing is written then.
        FitError: the finished set fails the geometric calibration; nothing is written.
    """
    if frames is not None and frames < 1:
        raise ValueError(f"frames must be >= 1, got {frames}")
    if settle < 0:
        raise ValueError(f"settle must be >= 0 seconds, got {settle}")
    out = Path(out_dir)
    _check_writable(out)
    rig, incomplete = capture_rig(rig_template, projector.resolution, camera.resolution)
    if response is not None and response != "estimate":
        rig = replace(rig, camera=replace(rig.camera, response=parse_response(response).spec))
    w, h = projector.resolution
    clock = clock if clock is not None else MonotonicClock()
    reader = FrameReader(camera, clock, log, retries)
    fixed = None if exposure is None or exposure == "auto" else float(exposure)
    for p in lock_controls(camera, allow_auto, fixed):
        log(f"warning: {p}")
    if camera.channels == 1:
        log(f"warning: {camera.name} is mono: {MONO_LIMITS}")
    session = Session(projector, camera, clock, reader, log, frames, settle)
    plan = capture_plan(w, h, camera.channels == 1)
    progress = Progress(len(plan), clock, log)
    prepare = (exposure == "auto", hdr_stops, hdr_stops is not None and response == "estimate")
    captured, rig = _take_plan(plan, session, prompt, progress, rig, prepare)
    projector.show(np.zeros((h, w, 3), np.uint8))
    if session.dimmer is not None and session.dimmer.dimmed:
        log(session.dimmer.summary())
    if session.bracket is not None and response == "estimate":
        response = None  # estimated from the brackets, not from the Gray code
    return _finish_set(
        out, rig, captured, response == "estimate", incomplete, camera.channels == 1, log
    )


def _finish_set(
    out: Path,
    rig: Rig,
    captured: dict[str, dict[str, np.ndarray]],
    estimate: bool,
    incomplete: bool,
    mono: bool,
    log: Log,
) -> list[Path]:
    """Check the captures (by stage and name, as :func:`_take_plan` returns them) as a set
    and write it to ``out``; returns the files. ``estimate``: first estimate the camera's
    response from the Gray code (into ``rig``); ``incomplete``: the rig.toml written asks for
    its geometry to be completed; ``mono``: a one-channel camera (:func:`_check_set`).

    Raises:
        FitError: the set fails the geometric calibration or a capture's check.
    """
    from viewcomp.calib.geo.camresponse import estimate_set_response

    cs = capture_set_from_raw(rig, captured["white"], captured["screen"], path=out)
    if estimate:
        found, misfit = estimate_set_response(cs)
        log(f"camera response estimated from the Gray code: {found.spec!r} (misfit {misfit:.4f})")
        rig = replace(rig, camera=replace(rig.camera, response=found.spec))
        cs = capture_set_from_raw(rig, captured["white"], captured["screen"], path=out)
    _check_set(cs, mono, log)
    paths = write_capture_set(out, rig, captured["white"], captured["screen"])
    if incomplete:
        with atomic_open(out / RIG_FILE) as f:
            f.write((COMPLETE_HEADER + rig_to_toml(rig)).encode("utf-8"))
        log(f"{out / RIG_FILE}: complete the geometry (see its first lines) before calibrating")
    return paths


def _take_plan(
    plan: list[Step],
    session: Session,
    prompt: Prompt,
    progress: Progress,
    rig: Rig,
    prepare: tuple[bool, tuple[float, ...] | None, bool],
) -> tuple[dict[str, dict[str, np.ndarray]], Rig]:
    """Show and capture every step of ``plan``, stage by stage (``prompt`` asked before each),
    each capture checked live and each stage ended by gray again (:func:`_end_of_stage`).

    Before the first capture the session is prepared (``prepare``: search the exposure, the
    HDR bracket's stops or None, estimate the response from a bracket) and the live checks
    made for the response it leaves. Returns the captures to write by stage (``"white"``,
    ``"screen"``) and name (codes, or merged linear values), and ``rig`` with that response.

    Raises:
        CaptureError: the user stopped, or a live check refused a capture.
    """
    checks: LiveChecks | None = None
    captured: dict[str, dict[str, np.ndarray]] = {"white": {}, "screen": {}}
    stage = ""
    for step in plan:
        if step.sub != stage:
            if stage and checks is not None:
                _end_of_stage(stage, checks, session.take, plan)
            stage = step.sub
            if not prompt(stage, STAGE_MESSAGES[stage]):
                raise CaptureError("capture stopped by the user; nothing was written")
            if checks is None:
                rig, checks = _prepare(session, rig, prepare)
                progress.start()
        rel = f"{step.sub}/{step.name}"
        image, clipped = session.take(step.pattern, rel)
        assert checks is not None  # the plan's first step opened its stage, which made them
        if clipped is None:
            checks.check(step.sub, step.name, image)
        else:
            checks.check_merged(step.sub, step.name, image, clipped)
        if not step.check_only:  # the reference shown again: checked, not written
            captured[step.sub][step.name] = image
        progress.step(rel)
    if checks is not None:
        _end_of_stage(stage, checks, session.take, plan)
    return captured, rig


def _prepare(
    session: Session, rig: Rig, prepare: tuple[bool, tuple[float, ...] | None, bool]
) -> tuple[Rig, LiveChecks]:
    """Prepare the session (``prepare`` as in :func:`_take_plan`) and make the live checks
    (mono ones for a one-channel camera) for the response it finds, else ``rig``'s; returns
    ``rig`` with that response and the checks."""
    search, hdr_stops, estimate = prepare
    found = session.prepare(search, hdr_stops, rig.camera.response_curve(), estimate)
    if found is not None:
        rig = replace(rig, camera=replace(rig.camera, response=found.spec))
    checks = (MonoChecks if session.camera.channels == 1 else LiveChecks)(
        rig.camera.response_curve(), session.projector.resolution
    )
    return rig, checks


def _check_set(cs: CaptureSet, mono: bool, log: Log) -> None:
    """Check the finished set as `viewcomp calibrate` will (a ``mono`` set: its geometry only,
    since colour order and mixing cannot be checked in it) and log the geometry's fit.

    Raises:
        FitError: the geometric calibration fails, or a capture fails its check.
    """
    from viewcomp.calib.geo.rectify import calibrate_geometry, rectify_capture_set

    if mono:
        # colour order and mixing cannot be checked in a mono set (calibrate refuses it)
        log("checking the set's geometry as `viewcomp calibrate` will")
        stats = dict(calibrate_geometry(cs).stats)
    else:
        log("checking the set as `viewcomp calibrate` will (geometry, saturation, order)")
        rectified, stats = rectify_capture_set(cs)
        check_captures(rectified)
    log(
        f"geometry: Zhang reprojection {stats['chessboard']['zhang_rms_px']:.3f} px RMS, "
        f"Gray-code map {stats['graycode']['rms_px']:.3f} px RMS, chessboard vs map "
        f"{stats['map']['chessboard_rms_px']:.3f} px RMS"
    )


def _end_of_stage(
    stage: str,
    checks: LiveChecks,
    take: Callable[[np.ndarray, str], tuple[np.ndarray, np.ndarray | None]],
    plan: list[Step],
) -> None:
    """Capture gray again (``take``: codes and None, or merged linear and its clipped mask)
    and compare it with the stage's first gray (not written)."""
    gray = next(s.pattern for s in plan if s.name == "gray")
    what = f"{stage}/gray (again, at the end)"
    image, clipped = take(gray, what)
    lin = checks.linear(image) if clipped is None else image
    checks.moved(stage, what, lin, clipped)
