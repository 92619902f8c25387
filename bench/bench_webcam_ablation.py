"""What costs the emulated webcam its accuracy: the hardware protocol's webcam case with one
impairment switched off at a time. Prints one JSON line per variant to stdout.

Each variant is the shipped webcam profile (:data:`viewcomp.calib.emu.profiles.WEBCAM`) with
one impairment removed (a profile override for this experiment only; the shipped profile is
not changed), run through :func:`viewcomp.calib.eval.hardware.hardware_case` (the real capture
procedure on the emulator, `calibrate`, compensation judged through the emulator's physics)
on the glossy magenta screen, 8 bits, beside the ideal pipeline: mean CIEDE2000 at 60 and 125
degrees and their ratio to ideal (the criterion is 1.15); ``--screen`` and ``--capture`` run
another screen (a measured material's .npz) or HDR. ``no_mosaic`` samples every channel
at every pixel (no Bayer mosaic, no demosaicking; the sensor and processing functions of
:mod:`viewcomp.calib.emu.camera` replaced for that variant). About 30 s a variant at 320x160
on an idle 2-core machine. Run from the repository root::

    .venv/bin/python bench/bench_webcam_ablation.py [--size 320x160] [--variants a,b,...]
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
import time
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

import cv2
import numpy as np

import viewcomp.calib.emu.camera as emu_camera
from viewcomp.calib.emu.profiles import WEBCAM, CameraProfile
from viewcomp.calib.eval.hardware import hardware_case

_OFF = {
    "mjpeg_quality": 0,
    "tone_s": 0.0,
    "sharpen": 0.0,
    "denoise": 0.0,
    "vignetting": 0.0,
    "readout": 0.0,
    "distortion": (0.0, 0.0, 0.0, 0.0, 0.0),
    "read_noise": 0.0,
    "full_well": 1e9,
    "blur_px": 0.0,
}
VARIANTS: dict[str, dict[str, Any]] = {
    "shipped": {},
    "density_1.2": {"density": 1.2},
    "no_mjpeg": {"mjpeg_quality": 0},
    "no_mosaic": {},
    "no_s_curve": {"tone_s": 0.0},
    "no_sharpen": {"sharpen": 0.0},
    "no_denoise": {"denoise": 0.0},
    "no_vignetting": {"vignetting": 0.0},
    "no_rolling_shutter": {"readout": 0.0},
    "no_distortion": {"distortion": (0.0, 0.0, 0.0, 0.0, 0.0)},
    "no_noise": {"read_noise": 0.0, "full_well": 1e9},
    "no_optics_blur": {"blur_px": 0.0},
    "all_off_but_density": _OFF,
    "all_off": {**_OFF, "density": 1.2},
}
_MOSAIC_FREE = ("no_mosaic", "all_off_but_density", "all_off")


def _full_colour_codes(
    sig: np.ndarray, p: CameraProfile, gain: float, rng: np.random.Generator
) -> np.ndarray:
    """:func:`viewcomp.calib.emu.camera.sensor_codes` without the mosaic: (Hc, Wc, 3)."""
    e = np.maximum(sig, 0.0) * np.float32(p.full_well)
    e = e + np.sqrt(e + np.float32(p.read_noise**2)) * rng.standard_normal(e.shape, np.float32)
    top = (1 << p.raw_bits) - 1
    return np.clip(np.rint(e * np.float32(gain * top / p.full_well)), 0, top).astype(np.uint16)


def _process_without_demosaic(raw: np.ndarray, wb: np.ndarray, p: CameraProfile) -> np.ndarray:
    """:func:`viewcomp.calib.emu.camera.webcam_process` on full-colour codes (no demosaic)."""
    enc = emu_camera.tone_curve(
        np.clip(raw * (wb / np.float32((1 << p.raw_bits) - 1)), 0, 1), p.tone_s
    )
    if p.denoise > 0:
        enc = cv2.GaussianBlur(enc, (0, 0), p.denoise)
    if p.sharpen > 0:
        enc = enc + np.float32(p.sharpen) * (enc - cv2.GaussianBlur(enc, (0, 0), 1.0))
    out = np.clip(np.rint(enc * 255.0), 0, 255).astype(np.uint8)
    return emu_camera.mjpeg(out, p.mjpeg_quality) if p.mjpeg_quality > 0 else out


@contextlib.contextmanager
def _mosaic_free(on: bool) -> Iterator[None]:
    saved = emu_camera.sensor_codes, emu_camera.webcam_process
    if on:
        emu_camera.sensor_codes = _full_colour_codes  # type: ignore[assignment]
        emu_camera.webcam_process = _process_without_demosaic
    try:
        yield
    finally:
        emu_camera.sensor_codes, emu_camera.webcam_process = saved


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="320x160")
    ap.add_argument("--variants", default=",".join(VARIANTS))
    ap.add_argument("--screen", default="magenta", help="a colour name or a material .npz")
    ap.add_argument("--capture", default="8bit", choices=["8bit", "hdr"])
    args = ap.parse_args()
    size = tuple(int(v) for v in args.size.lower().split("x"))
    ideal: dict[str, Any] = {}
    for name in args.variants.split(","):
        t0 = time.perf_counter()
        prof = replace(WEBCAM, **VARIANTS[name])
        with _mosaic_free(name in _MOSAIC_FREE):
            screen = Path(args.screen) if args.screen.endswith(".npz") else args.screen
            row = hardware_case(prof, screen, args.capture, size, angles=(60.0, 125.0), ideal=ideal)
        out: dict[str, Any] = {"variant": name, "refused": row["refused"]}
        if not row["refused"]:
            for a in ("60", "125"):
                e, i = row["emulated"][a]["compensated"], row["ideal"][a]["compensated"]
                out[a] = {"emulated": round(e, 2), "ideal": round(i, 2), "ratio": round(e / i, 3)}
        out["seconds"] = round(time.perf_counter() - t0, 1)
        print(json.dumps(out), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
