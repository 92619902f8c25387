"""The capture procedure of `viewcomp capture`: patterns in, a checked capture set out.

For each pattern, in order: show it on the projector, wait ``settle`` seconds, grab and
average ``frames`` camera frames, and check the capture at once, so that a problem is named
while the user can still fix it:

- saturated: more than 0.5% of the lit pixel-channels at the maximum code -> lower the
  exposure (or the projector's brightness);
- too dark / pattern not visible: the projected image does not stand out from black -> check
  the monitor, the camera's aim, the exposure;
- wrong pattern: red, green, blue must raise their own camera channel most over gray;
- camera moved: the projector frame's edges shift by more than 1 camera pixel from the
  stage's first gray capture, or the chessboard corners from the white stage's;
- chessboard not found.

The sets: ``white/`` on the ideal matte white screen (Table 1, black, chessboard), after a
prompt to put it in place; then ``screen/`` on the real screen (the same, plus the Gray code
of OpenCV structured_light). Each stage ends with a second gray capture, compared with its
first (the camera moved during the stage). Before anything is written, the whole set goes
through the geometric calibration that `viewcomp calibrate` will run
(:func:`viewcomp.calib.geo.rectify.rectify_capture_set`) and its saturation and darkness checks:
a set that is written calibrates. A refused capture raises
:class:`~viewcomp.calib.io.imageio.CaptureError` (or ``FitError``) and nothing is written.

With an HDR bracket (``hdr_stops``, `capture --hdr`), each capture is the camera's frames at
every relative exposure (:class:`Bracket`), merged into float32 linear light as it is taken;
"saturated" then means clipped even in the shortest exposure, and the set is written as
``.npy``.

Prompts go through a callable ``prompt(stage, message) -> bool`` (False: stop), so tests
and unattended runs (``--yes``) answer them.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from viewcomp.calib.geo.checks import MIN_PEAK, MOVE_LIMIT_PX, frame_shift
from viewcomp.calib.geo.chessboard import find_corners
from viewcomp.calib.hw.devices import Camera, DeviceError, Projector
from viewcomp.calib.io.atomic import atomic_open
from viewcomp.calib.io.captureset import RIG_FILE, capture_set_from_raw, write_capture_set
from viewcomp.calib.io.checks import DARK_LIMIT, SATURATION_LIMIT, check_captures
from viewcomp.calib.io.hdr import check_stops, merge_exposures
from viewcomp.calib.io.imageio import CaptureError, to_linear
from viewcomp.calib.io.patterns import table1_patterns
from viewcomp.calib.sim.simcamera import geometric_patterns
from viewcomp.calib.world.response import Response, parse_response
from viewcomp.calib.world.rig import CaptureSpec, Rig, default_rig, rig_to_toml

Prompt = Callable[[str, str], bool]
Log = Callable[[str], None]

VISIBLE_LIMIT = 0.01  # linear: gray - black must exceed this to count as lit
MIN_LIT_FRACTION = 0.005  # of the camera image

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
TABLE1_ORDER = ("black", "gray", "red", "green", "blue", "ramp")

COMPLETE_HEADER = """\
# TO COMPLETE: `viewcomp capture` measured the resolutions only. Measure and enter the
# projector's and the camera's position, look_at and fov_y (metres, degrees; the world frame of
# docs/MODEL.md of viewcomp: the screen is z = 0, +y up, +z toward the audience) and the
# camera's response, then run `viewcomp calibrate`. The lens distortion is estimated by
# calibrate.
"""


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


def capture_rig(
    template: Rig | None, projector: tuple[int, int], camera: tuple[int, int]
) -> tuple[Rig, bool]:
    """The rig.toml of the new set: the template's (or the example rig's) geometry with the
    devices' resolutions and ``space = "camera"``. Returns it and whether the user must still
    complete it (no template given)."""
    base = template if template is not None else default_rig()
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


class LiveChecks:
    """The checks run on each capture as it arrives (see the module doc).

    ``response`` linearises the camera's codes; ``projector_size`` (W, H) places the
    chessboard's corners.
    """

    def __init__(self, response: Response, projector_size: tuple[int, int]) -> None:
        self.response = response
        self.projector_size = projector_size
        self.black: dict[str, np.ndarray] = {}
        self.gray: dict[str, np.ndarray] = {}
        self.lit: dict[str, np.ndarray] = {}
        self.corners: dict[str, np.ndarray] = {}
        self.pending: dict[str, np.ndarray] = {}

    def linear(self, raw: np.ndarray) -> np.ndarray:
        """(H, W, 3) codes -> float32 linear 0..1."""
        return to_linear(raw, self.response)

    def _clipped_fraction(self, sub: str, at_top: np.ndarray) -> float:
        """Fraction of the lit pixels (all before ``sub``'s gray) with a channel at the top:
        ``at_top`` (H, W, 3) bool."""
        mask = self.lit.get(sub)
        hit = np.any(at_top, axis=2) if mask is None else at_top[mask]
        return float(np.count_nonzero(hit)) / max(hit.size, 1)

    def check(self, sub: str, name: str, raw: np.ndarray) -> None:
        """Check one capture; raises CaptureError naming it and the fix."""
        rel = f"{sub}/{name}"
        if raw.ndim != 3 or raw.shape[2] != 3 or raw.dtype not in (np.uint8, np.uint16):
            raise CaptureError(f"{rel}: the camera returned {raw.shape} {raw.dtype}, not RGB")
        top = 255 if raw.dtype == np.uint8 else 65535
        frac = self._clipped_fraction(sub, raw >= top)
        if frac > SATURATION_LIMIT:
            raise CaptureError(
                f"{rel}: {frac:.1%} of the lit pixels are at the maximum code (saturated): "
                "lower the camera's exposure (--exposure) or the projector's brightness, or "
                "capture with --hdr, and capture again"
            )
        self.check_linear(sub, name, self.linear(raw))

    def check_merged(self, sub: str, name: str, lin: np.ndarray, clipped: np.ndarray) -> None:
        """Check one HDR capture: ``lin`` (H, W, 3) float32 merged linear light, ``clipped``
        (H, W, 3) bool the pixel-channels clipped in every frame of the bracket."""
        rel = f"{sub}/{name}"
        frac = self._clipped_fraction(sub, clipped)
        if frac > SATURATION_LIMIT:
            raise CaptureError(
                f"{rel}: {frac:.1%} of the lit pixels are clipped even in the bracket's shortest "
                "exposure: lower the camera's exposure (--exposure) and capture again"
            )
        self.check_linear(sub, name, lin)

    def check_linear(self, sub: str, name: str, lin: np.ndarray) -> None:
        """The checks of :meth:`check` after saturation, on the linear capture (H, W, 3)."""
        rel = f"{sub}/{name}"
        if name == "black":
            self.black[sub] = lin
            return
        if name == "gray":
            self._first_gray(sub, rel, lin)
            return
        if sub not in self.gray:
            raise CaptureError(f"{rel}: captured before {sub}/gray; use capture_plan's order")
        if name in ("red", "green", "blue"):
            self._colour(sub, rel, name, lin)
        if name == "chessboard":
            self._chessboard(sub, rel, lin)
        if name.startswith("graycode_") and name[9:].isdigit():
            k = int(name[9:])
            if k % 2 == 0:
                self.pending[sub] = lin
                return
            lin = lin + self.pending.pop(sub, np.zeros_like(lin))  # a plane + its inverse
        if name != "graycode_black":
            self.moved(sub, rel, lin)

    def _first_gray(self, sub: str, rel: str, lin: np.ndarray) -> None:
        black = self.black.get(sub, np.zeros_like(lin))
        diff = (lin - black).mean(axis=2)
        peak = float(np.percentile(diff, 99.5))
        lit = diff > max(VISIBLE_LIMIT, 0.3 * peak)
        if peak < VISIBLE_LIMIT or lit.mean() < MIN_LIT_FRACTION:
            raise CaptureError(
                f"{rel}: the projected image is not visible to the camera (gray is at most "
                f"{peak:.3f} above black, lit area {lit.mean():.2%} of the frame): check that "
                "the window is on the projector (--monitor, see --list-monitors), that the "
                "camera sees the screen, and the exposure"
            )
        level = float(lin[lit].mean())
        if level < DARK_LIMIT:
            raise CaptureError(
                f"{rel}: too dark (mean linear level {level:.4f} where the projector lights): "
                "raise the camera's exposure or darken the room, and capture again"
            )
        self.gray[sub] = lin
        self.lit[sub] = lit

    def _colour(self, sub: str, rel: str, name: str, lin: np.ndarray) -> None:
        c = ("red", "green", "blue").index(name)
        d = (lin - self.gray[sub])[self.lit[sub]].mean(axis=0)
        if d[c] <= 0 or d[c] <= max(d[(c + 1) % 3], d[(c + 2) % 3]):
            raise CaptureError(
                f"{rel}: the {name} pattern does not raise the camera's {name} channel most "
                f"(change over gray R,G,B = {d[0]:+.4f}, {d[1]:+.4f}, {d[2]:+.4f}): check the "
                "projector's colour mode and that the window is on the projector"
            )

    def _chessboard(self, sub: str, rel: str, lin: np.ndarray) -> None:
        corners = find_corners(lin, self.projector_size, rel).camera
        self.corners[sub] = corners
        if sub == "screen" and "white" in self.corners:
            shift = float(np.sqrt(np.mean(np.sum((corners - self.corners["white"]) ** 2, 1))))
            if shift > MOVE_LIMIT_PX:
                raise CaptureError(
                    f"{rel}: the chessboard lies {shift:.1f} camera px from where it was on the "
                    "white screen: the camera moved, or the real screen is not where the white "
                    "one was; put it in the same place, fix the camera, and capture again"
                )

    def moved(self, sub: str, rel: str, lin: np.ndarray) -> None:
        """Refuse a capture whose frame edges moved from the stage's first gray capture."""
        d, peak = frame_shift(self.gray[sub], lin)
        if peak < MIN_PEAK:
            raise CaptureError(
                f"{rel}: the projector's frame is not where {sub}/gray has it (no clear match): "
                "the camera moved a lot, or the projector stopped showing; fix the camera and "
                "capture again"
            )
        if d > MOVE_LIMIT_PX:
            raise CaptureError(
                f"{rel}: the projector's frame moved {d:.1f} camera px since {sub}/gray: the "
                "camera moved (or was bumped); fix it, lock zoom and focus, and capture again"
            )


def relative_exposure(base: float, value: float) -> float:
    """An exposure ``value`` relative to ``base``, both in the driver's units: linear (V4L2's
    100 us steps, the simulated camera's gain) when ``base`` > 0; log2 of seconds (DirectShow,
    MSMF: -13 .. 0) when ``base`` <= 0."""
    return value / base if base > 0 else 2.0 ** (value - base)


def exposure_value(base: float, relative: float) -> float:
    """The driver value that is ``relative`` times ``base`` (the inverse of
    :func:`relative_exposure`)."""
    return base * relative if base > 0 else base + math.log2(relative)


class Bracket:
    """HDR captures: each one the camera's frames at every relative exposure of ``stops``
    (set through :meth:`Camera.set_exposure`, read back as the camera reports it), merged
    by :func:`~viewcomp.calib.io.hdr.merge_exposures` into float32 linear light in units of
    the camera's exposure when the bracket starts (its base, restored after each capture).

    Raises (at construction or :meth:`grab`): DeviceError when the camera's exposure cannot
    be set or does not change.
    """

    def __init__(
        self, camera: Camera, stops: tuple[float, ...], response: Response, log: Log
    ) -> None:
        self.camera = camera
        self.stops = check_stops(stops)
        self.response = response
        self.log = log
        self.base = camera.get_exposure()
        self.reported: tuple[float, ...] | None = None

    def grab(self, frames: int) -> tuple[np.ndarray, np.ndarray]:
        """One merged capture: ((H, W, 3) float32 linear, (H, W, 3) bool clipped in every
        frame). Frames whose read-back exposure repeats an earlier one are dropped (a driver
        at the end of its range)."""
        raws: list[np.ndarray] = []
        rels: list[float] = []
        try:
            for s in self.stops:
                got = relative_exposure(
                    self.base, self.camera.set_exposure(exposure_value(self.base, s))
                )
                if not (math.isfinite(got) and got > 0) or any(
                    abs(got - r) <= 1e-6 * r for r in rels
                ):
                    continue
                raws.append(self.camera.grab(frames))
                rels.append(got)
        finally:
            self.camera.set_exposure(self.base)
        if len(rels) < 2:
            raise DeviceError(
                f"the camera does not change its exposure (asked for {len(self.stops)} relative "
                f"exposures from {self.base:g}, it reports the same): --hdr needs a camera whose "
                "exposure can be set; capture without --hdr"
            )
        if self.reported is None:
            self.reported = tuple(rels)
            self.log(
                "HDR bracket: relative exposures "
                + ", ".join(f"1/{1 / r:.4g}" if r < 1 else f"{r:.4g}" for r in rels)
                + f" of {self.base:g} (as the camera reports them)"
            )
        return merge_exposures(raws, rels, self.response)


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
    frames: int = 8,
    settle: float = 0.5,
    sleep: Callable[[float], None] = time.sleep,
    response: str | float | None = None,
    hdr_stops: tuple[float, ...] | None = None,
) -> list[Path]:
    """Capture a camera-space set into ``out_dir`` (see the module doc); returns the files.

    Args:
        out_dir: a new or empty folder, or an old capture set (its files are replaced).
        projector, camera: the devices (:mod:`viewcomp.calib.hw.devices`).
        rig_template: rig.toml geometry to keep (its resolutions are replaced by the
            devices'); None: the example rig, written with a "to complete" note.
        prompt: asks the user to swap screens; returning False stops (nothing written).
        log: progress and warnings.
        frames: camera frames averaged per capture (>= 1).
        settle: seconds between showing a pattern and grabbing (projector and camera latency).
        sleep: the waiting function (tests pass a no-op).
        response: the camera's response to write: None keeps the template's (sRGB without
            one), ``"estimate"`` estimates it from the Gray-code captures (light adds up:
            :func:`viewcomp.calib.geo.camresponse.estimate_response`), otherwise a rig.toml value.
        hdr_stops: None for one exposure per capture (encoded codes, written as PNG); or the
            relative exposures of an HDR bracket (:class:`Bracket`): every capture is taken at
            each and merged, written as float32 linear ``.npy``. Needs a known response (not
            ``"estimate"``) and a camera whose exposure can be set.

    Raises:
        CaptureError: a capture is refused (the message names it and the fix), the user
            stopped, or the folder cannot hold a capture set. Nothing is written then.
        FitError: the finished set fails the geometric calibration; nothing is written.
    """
    from viewcomp.calib.geo.camresponse import estimate_set_response
    from viewcomp.calib.geo.rectify import rectify_capture_set

    if frames < 1:
        raise ValueError(f"frames must be >= 1, got {frames}")
    if settle < 0:
        raise ValueError(f"settle must be >= 0 seconds, got {settle}")
    if hdr_stops is not None and response == "estimate":
        raise CaptureError(
            "--hdr needs the camera's response to merge the bracket: give --response "
            "(srgb, linear or a gamma) or a --rig with one; estimating it from the Gray code "
            "needs 8-bit captures"
        )
    out = Path(out_dir)
    _check_writable(out)
    rig, incomplete = capture_rig(rig_template, projector.resolution, camera.resolution)
    if response is not None and response != "estimate":
        rig = replace(rig, camera=replace(rig.camera, response=parse_response(response).spec))
    w, h = projector.resolution
    problems = camera.lock()
    for p in problems:
        log(f"warning: {p}")
    checks = LiveChecks(rig.camera.response_curve(), (w, h))
    bracket = (
        None if hdr_stops is None else Bracket(camera, hdr_stops, rig.camera.response_curve(), log)
    )

    def take() -> tuple[np.ndarray, np.ndarray | None]:
        """One capture: (encoded codes, None), or with a bracket (merged float32 linear,
        pixel-channels clipped in every frame)."""
        if bracket is None:
            return camera.grab(frames), None
        return bracket.grab(frames)

    captured: dict[str, dict[str, np.ndarray]] = {"white": {}, "screen": {}}
    plan = capture_plan(w, h)
    stage = ""
    for i, step in enumerate(plan):
        if step.sub != stage:
            if stage:
                _end_of_stage(stage, projector, checks, take, settle, sleep, plan)
            stage = step.sub
            if not prompt(stage, STAGE_MESSAGES[stage]):
                raise CaptureError("capture stopped by the user; nothing was written")
        projector.show(step.pattern)
        sleep(settle)
        image, clipped = take()
        if clipped is None:
            checks.check(step.sub, step.name, image)
        else:
            checks.check_merged(step.sub, step.name, image, clipped)
        captured[step.sub][step.name] = image
        log(f"{step.sub}/{step.name} ({i + 1}/{len(plan)})")
    _end_of_stage(stage, projector, checks, take, settle, sleep, plan)
    projector.show(np.zeros((h, w, 3), np.uint8))

    cs = capture_set_from_raw(rig, captured["white"], captured["screen"], path=out)
    if response == "estimate":
        found, misfit = estimate_set_response(cs)
        log(f"camera response estimated from the Gray code: {found.spec!r} (misfit {misfit:.4f})")
        rig = replace(rig, camera=replace(rig.camera, response=found.spec))
        cs = capture_set_from_raw(rig, captured["white"], captured["screen"], path=out)
    log("checking the set as `viewcomp calibrate` will (geometry, saturation, order)")
    rectified, stats = rectify_capture_set(cs)
    check_captures(rectified)
    log(
        f"geometry: Zhang reprojection {stats['chessboard']['zhang_rms_px']:.3f} px RMS, "
        f"Gray-code map {stats['graycode']['rms_px']:.3f} px RMS, chessboard vs map "
        f"{stats['map']['chessboard_rms_px']:.3f} px RMS"
    )
    paths = write_capture_set(out, rig, captured["white"], captured["screen"])
    if incomplete:
        with atomic_open(out / RIG_FILE) as f:
            f.write((COMPLETE_HEADER + rig_to_toml(rig)).encode("utf-8"))
        log(f"{out / RIG_FILE}: complete the geometry (see its first lines) before calibrating")
    return paths


def _end_of_stage(
    stage: str,
    projector: Projector,
    checks: LiveChecks,
    take: Callable[[], tuple[np.ndarray, np.ndarray | None]],
    settle: float,
    sleep: Callable[[float], None],
    plan: list[Step],
) -> None:
    """Capture gray again (``take``: codes and None, or merged linear and its clipped mask)
    and compare it with the stage's first gray (not written)."""
    gray = next(s.pattern for s in plan if s.name == "gray")
    projector.show(gray)
    sleep(settle)
    image, clipped = take()
    lin = checks.linear(image) if clipped is None else image
    checks.moved(stage, f"{stage}/gray (again, at the end)", lin)
