"""`viewcomp evaluate --protocol hardware`: the capture procedure on emulated devices, end to end.

For each camera profile of the hardware emulator (:mod:`viewcomp.calib.emu`: a UVC webcam, a
DSLR, a mono machine-vision camera, all with a DLP projector) and each screen (the built-in
glossy magenta, and every measured material of a folder), 8-bit and HDR:

1. **capture**: :func:`~viewcomp.calib.hw.procedure.run_capture` on the emulated devices - the
   code `viewcomp capture` runs on real hardware - into a capture set on disk; the emulator's
   clock says how long the capture would take on the real devices;
2. **calibrate** the set as `viewcomp calibrate` does (read back from disk);
3. **render**: natural images compensated (per-pixel method) for viewers at 60, 90 and 125
   degrees;
4. **what the viewer sees**: the emulator's own physics (its DLP projector averaged over whole
   refresh periods, the true screen, an ideal eye) of the projected images, against what the
   white screen shows of the image: mean CIEDE2000.

Beside it, ``ideal``: the same calibration and rendering on ideal projector-space captures of
the same screen and projector by a camera of the same kind - the emulator's truth seen from the
camera's position on the projector grid, in float linear light (no lens, no noise, no clipping,
no device at all) - so the difference is what the devices cost. A mono camera's ideal captures
are mono too (the emulated sensor's own weights over the colour channels, the per-primary
patterns added): its pipeline is the per-primary model (docs/MODEL.md, "Mono cameras"), which
no device can make better than an ideal mono camera does; its rows also carry
``ideal_colour``, the ideal colour camera's, which says what seeing no colour costs.
``original`` is the image projected as it is. A capture or a calibration that is refused is a
result: the row says why.
"""

from __future__ import annotations

import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from viewcomp.calib.comp.compensation import Compensation
from viewcomp.calib.emu.camera import MONO_WEIGHTS
from viewcomp.calib.emu.emulator import Emulator, open_emulator
from viewcomp.calib.errors import FitError
from viewcomp.calib.eval.adapted import adapted_delta_e
from viewcomp.calib.eval.metrics import delta_e2000
from viewcomp.calib.eval.testimages import natural_images
from viewcomp.calib.fit.calibrate import Calibration, calibrate
from viewcomp.calib.io.captureset import capture_set_from_raw, read_capture_set
from viewcomp.calib.io.hdr import DEFAULT_STOPS
from viewcomp.calib.io.imageio import CaptureError
from viewcomp.calib.io.patterns import primary_patterns
from viewcomp.calib.sim.simcamera import written_rig
from viewcomp.calib.sim.simulate import projector_patterns
from viewcomp.calib.world.response import parse_response
from viewcomp.calib.world.rig import CaptureSpec

PROFILES = ("webcam", "dslr", "mono12")
HARDWARE_ANGLES = (60.0, 90.0, 125.0)
HARDWARE_SIZE = (320, 160)
CAPTURES = ("8bit", "hdr")
#: Mean dE of the emulated pipeline at most this many times the ideal one's (60 and 125 deg).
WITHIN = 1.15
IMAGES = ("astronaut", "coffee", "chelsea")

Progress = Callable[[str], None]
_SRGB = parse_response("srgb")


def _encode(linear: np.ndarray) -> np.ndarray:
    """Linear light (H, W, 3) -> sRGB codes (the metric's encoding), clipped."""
    enc = _SRGB.encode(np.clip(linear, 0.0, 1.0).astype(np.float32))
    return np.rint(np.asarray(enc) * 255.0).astype(np.uint8)


def emulated_capture(
    emu: Emulator, out: Path, hdr: bool, frames: int | None = None, log: Progress | None = None
) -> tuple[list[Path], float]:
    """Run the real capture procedure on ``emu`` into ``out``; returns the files and the
    seconds it took on the emulated devices' clock. ``frames`` averaged per capture; None, as
    `viewcomp capture` takes by default (16 for the webcam's 8-bit frames, 8 for the others':
    :func:`~viewcomp.calib.hw.frames.default_frames`; the protocol measures the default)."""
    from viewcomp.calib.hw.procedure import run_capture

    # raw frames are linear; an encoding camera's curve is what a user does not know: it is
    # estimated from the captures, as `viewcomp capture` does without a --response
    written = written_rig(emu.truth.rig)
    template = replace(written, camera=replace(written.camera, response="linear"))
    response = None if emu.profile.linear else "estimate"

    def prompt(stage: str, _message: str) -> bool:
        emu.swap_screen(stage)
        return True

    start = emu.clock.now()
    paths = run_capture(
        out,
        emu.projector,
        emu.camera,
        rig_template=template,
        prompt=prompt,
        log=log or (lambda _m: None),
        frames=frames,
        clock=emu.clock,
        response=response,
        hdr_stops=DEFAULT_STOPS if hdr else None,
        exposure="auto",
    )
    return paths, emu.clock.now() - start


def _mono(linear: np.ndarray) -> np.ndarray:
    """Linear camera RGB (H, W, 3) -> what the emulated mono sensor sees, as R = G = B."""
    y = np.asarray(linear, np.float32) @ MONO_WEIGHTS
    return np.repeat(y[..., None], 3, axis=2)


def ideal_calibration(emu: Emulator, mono: bool = False) -> Calibration:
    """The calibration from ideal projector-space captures of the emulator's own world: what
    an ideal camera at the calibration camera's position sees on the projector grid (float
    linear, whole refresh periods). ``mono``: an ideal mono camera (the emulated mono
    sensor's weights, with the per-primary patterns a mono capture adds)."""
    truth = emu.truth
    rig = replace(truth.rig, capture=CaptureSpec(space="projector"))
    cam = np.asarray(rig.camera.position, np.float64)
    pats = projector_patterns(rig.projector.resolution, True)
    if mono:
        pats |= primary_patterns(*rig.projector.resolution)
    seen = _mono if mono else (lambda x: np.asarray(x, np.float32))
    sets = {
        name: {k: seen(truth.observe_linear(name, img, cam)) for k, img in pats.items()}
        for name in ("white", "screen")
    }
    return calibrate(capture_set_from_raw(rig, sets["white"], sets["screen"]))


def seen_errors(
    emu: Emulator, cal: Calibration, images: dict[str, np.ndarray], angles: Sequence[float]
) -> dict[str, dict[str, float]]:
    """Per angle (key ``f"{angle:g}"``) the mean over ``images`` of the dE of ``compensated``
    (the per-pixel method of ``cal`` for that viewer) and ``original``, both against the
    white screen, seen through the emulator's physics."""
    truth = emu.truth
    comp = Compensation(cal, "pixel")
    out: dict[str, dict[str, float]] = {}
    for a in angles:
        eye = cal.eye(float(a))
        de: dict[str, list[float]] = {k: [] for k in ("compensated", "original")}
        de |= {f"{k}_adapted": [] for k in ("compensated", "original")}
        for image in images.values():
            ideal = _encode(truth.observe_linear("white", image, eye))
            shown, _ = comp.compensate_image(image, eye)
            for k, img in (("compensated", shown), ("original", image)):
                seen = _encode(truth.observe_linear("screen", img, eye))
                de[k].append(delta_e2000(seen, ideal))
                de[f"{k}_adapted"].append(adapted_delta_e(seen, ideal).de)
        out[f"{a:g}"] = {k: float(np.mean(v_)) for k, v_ in de.items()}
    return out


def hardware_case(
    profile: str,
    screen: str | Path,
    capture: str,
    size: tuple[int, int] = HARDWARE_SIZE,
    seed: int = 0,
    angles: Sequence[float] = HARDWARE_ANGLES,
    image_names: Sequence[str] = IMAGES,
    ideal: dict[str, Any] | None = None,
    progress: Progress | None = None,
) -> dict[str, Any]:
    """One row: ``profile`` x ``screen`` (a colour name, glossy, or a material ``.npz``) x
    ``capture`` ("8bit" or "hdr"). ``ideal`` caches the ideal pipelines' errors per screen and
    camera kind (colour or mono; they depend on neither the profile nor the capture)."""
    if capture not in CAPTURES:
        raise ValueError(f"capture must be one of {CAPTURES}, got {capture!r}")
    emu = open_emulator(profile, screen, seed=seed, projector_size=size)
    w, h = size
    imgs = {k: v for k, v in natural_images(w, h).items() if k in image_names}
    row: dict[str, Any] = {
        "profile": profile,
        "screen": emu.truth.screens["screen"].name,
        "capture": capture,
        "refused": None,
    }
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="viewcomp-hw-") as tmp:
        try:
            _, seconds = emulated_capture(emu, Path(tmp) / "caps", capture == "hdr")
            row["capture_seconds"] = round(seconds, 1)
            cal = calibrate(read_capture_set(Path(tmp) / "caps"))
        except (CaptureError, FitError) as exc:
            row["refused"] = str(exc)
    if row["refused"] is None:
        row["emulated"] = seen_errors(emu, cal, imgs, angles)
    cache = ideal if ideal is not None else {}
    kinds = [("ideal", False)]
    if emu.camera.channels == 1:
        kinds = [("ideal", True), ("ideal_colour", False)]
    for field, mono in kinds:
        key = f"{row['screen']}/{'mono' if mono else 'colour'}"
        if key not in cache:
            cache[key] = seen_errors(emu, ideal_calibration(emu, mono), imgs, angles)
        row[field] = cache[key]
    row["run_seconds"] = round(time.perf_counter() - t0, 1)
    emu.close()
    if progress:
        what = "refused: " + str(row["refused"])[:120] if row["refused"] else "done"
        progress(f"hardware: {profile} {row['screen']} ({capture}) {what}")
    return row


def check_hardware(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """The criteria: no capture refused; the emulated pipeline's mean dE within
    :data:`WITHIN` times the ideal one's (the same kind of camera) at 60 and 125 degrees, per
    row. ``ratios_colour``: a mono row's against the ideal colour camera's (not a criterion:
    what seeing no colour costs)."""
    refused = [f"{r['profile']}/{r['screen']}/{r['capture']}" for r in rows if r["refused"]]
    ratios: dict[str, float] = {}
    colour: dict[str, float] = {}
    for r in rows:
        if r["refused"]:
            continue
        for a in ("60", "125"):
            name = f"{r['profile']}/{r['screen']}/{r['capture']}@{a}"
            e = r["emulated"][a]["compensated"]
            ratios[name] = round(e / r["ideal"][a]["compensated"], 4)
            if "ideal_colour" in r:
                colour[name] = round(e / r["ideal_colour"][a]["compensated"], 4)
    return {
        "refused": refused,
        "ratios": ratios,
        "ratios_colour": colour,
        "within": all(v <= WITHIN for v in ratios.values()) and not refused,
    }


def hardware(
    screens: Sequence[str | Path],
    profiles: Sequence[str] = PROFILES,
    captures: Sequence[str] = CAPTURES,
    size: tuple[int, int] = HARDWARE_SIZE,
    seed: int = 0,
    progress: Progress | None = None,
) -> dict[str, Any]:
    """The hardware protocol over ``screens`` (colour names and material paths) x
    ``profiles`` x ``captures``; returns ``{"hardware": rows, "hardware_checks": ...}``."""
    ideal: dict[str, Any] = {}
    cases = [(p, s, c) for s in screens for p in profiles for c in captures]
    rows: list[dict[str, Any]] = []
    t0 = time.perf_counter()
    for p, s, c in cases:
        rows.append(hardware_case(p, s, c, size, seed, ideal=ideal, progress=progress))
        if progress:  # the rows so far at their mean pace
            left = (time.perf_counter() - t0) / len(rows) * (len(cases) - len(rows))
            progress(f"hardware: {len(rows)}/{len(cases)} rows, about {left / 60:.0f} min left")
    return {"hardware": rows, "hardware_checks": check_hardware(rows)}
