"""A calibration's verdict: good, usable or poor, and why, in words an operator acts on.

Judged from what the bundle keeps (``Calibration.info`` and the fits), so it can be given for
any bundle, not only at the end of `viewcomp calibrate`. Each :class:`Finding` measures one
thing against two thresholds (good / usable; beyond usable it is poor). The calibration's
level is its worst finding's; the paper's method's own fit is judged apart (it limits that
method only).

The thresholds come from simulated captures of one glossy magenta screen (320x160 and
160x80, seed 0): at the default exposure the white screen at full output reaches 0.66 of
the camera's range, the gray capture's noise is 1.7-2.1 % and the per-pixel model's ramp
residual 0.6 %; at 0.15 of that exposure 0.13, 5.4-7.1 % and 2.4 %. A good capture sits
well inside each; the under-exposed one is poor on exposure and noise.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from viewcomp.calib.fit.calibrate import Calibration

LEVELS = ("good", "usable", "poor")


@dataclass(frozen=True)
class Finding:
    """One measured aspect: ``name``, its ``value``, the ``level`` it earns, the two
    thresholds (``good``, ``usable``; ``higher_is_better`` says their direction), the
    ``scope`` it limits ("calibration" or "paper method") and ``advice`` when not good."""

    name: str
    value: float
    level: str
    good: float
    usable: float
    higher_is_better: bool
    scope: str
    what: str
    advice: str

    def sentence(self) -> str:
        """One line for the terminal."""
        cmp = ">=" if self.higher_is_better else "<="
        text = f"{self.name} {self.value:.4g}: {self.what} ({self.level}; good {cmp} {self.good:g})"
        return text if self.level == "good" else f"{text}; {self.advice}"


def _grade(value: float, good: float, usable: float, higher: bool) -> str:
    if not math.isfinite(value):
        return "poor"
    if higher:
        return "good" if value >= good else "usable" if value >= usable else "poor"
    return "good" if value <= good else "usable" if value <= usable else "poor"


def _finding(
    name: str,
    value: float,
    good: float,
    usable: float,
    higher: bool,
    what: str,
    advice: str,
    scope: str = "calibration",
) -> Finding:
    level = _grade(float(value), good, usable, higher)
    return Finding(name, float(value), level, good, usable, higher, scope, what, advice)


@dataclass(frozen=True)
class Verdict:
    """``level`` of the calibration (good / usable / poor), the ``paper_level`` of the
    paper's method (None when it was not fitted) and every finding."""

    level: str
    paper_level: str | None
    findings: tuple[Finding, ...]

    @property
    def reasons(self) -> list[str]:
        """The sentences of the findings that are not good, worst first."""
        bad = [f for f in self.findings if f.level != "good"]
        bad.sort(key=lambda f: -LEVELS.index(f.level))
        return [f.sentence() for f in bad]

    def to_json(self) -> dict[str, Any]:
        """JSON-ready form (calibration.json)."""
        return {
            "level": self.level,
            "paper_level": self.paper_level,
            "reasons": self.reasons,
            "findings": [asdict(f) for f in self.findings],
        }


def _capture_findings(cal: Calibration) -> list[Finding]:
    """Exposure, noise, fit against noise, ramp residual and clipping."""
    info = cal.info
    q = info.get("quality", {})
    h, w = cal.pixel.geometry.refl.shape[:2]
    found: list[Finding] = []
    if "full_output" in q:
        found.append(
            _finding(
                "exposure",
                q["full_output"],
                0.35,
                0.2,
                True,
                "the white screen at the projector's full output, as a fraction of the camera's "
                "range",
                "raise the camera's exposure (capture --exposure, or let capture search it) so the "
                "white screen at full output reaches about half the range, and capture again",
            )
        )
    if "noise" in q:
        noise = float(max(q["noise"]))
        found.append(
            _finding(
                "noise",
                noise,
                0.03,
                0.05,
                False,
                "relative noise of the white screen's gray capture (largest channel)",
                "raise the exposure, average more frames (capture --frames) or darken the room, "
                "and capture again",
            )
        )
        rms = float(np.max(cal.pixel.lobe.rms))
        found.append(
            _finding(
                "fit_vs_noise",
                rms / max(math.sqrt(2.0) * noise, 1e-9),
                2.0,
                4.0,
                False,
                "the per-pixel lobe's residual over the noise of a screen/white ratio",
                "the specular model does not describe this screen beyond the captures' noise: "
                "check that nothing moved between the white and the real screen, and that the "
                "real screen is flat and fixed",
            )
        )
    if "ramp_residual_median" in q:
        found.append(
            _finding(
                "ramp_residual",
                q["ramp_residual_median"],
                0.015,
                0.03,
                False,
                "median error of the per-pixel model on the real screen's ramp capture, relative "
                "to each pixel's full level",
                "the model does not reproduce a capture it was not built from: noisy captures "
                "(see noise), or the projector or camera changed between the captures (auto "
                "exposure, a lamp warming up): lock the camera, let the projector warm up, and "
                "capture again",
            )
        )
    found.append(
        _finding(
            "clipped",
            int(info.get("clipped_pixels", 0)) / float(h * w),
            0.001,
            0.02,
            False,
            "fraction of the pixels clipped in some capture (left out of the fits)",
            "capture with --hdr (or lower the exposure) so the highlight is measured",
        )
    )
    return found


def _geometry_findings(geo: dict[str, Any]) -> list[Finding]:
    """Camera space: coverage, Gray-code decoding and the map against the chessboard."""
    found: list[Finding] = []
    gc = geo.get("graycode") or {}
    ph = geo.get("phase") or {}
    decoded = [
        v
        for v in (gc.get("decoded_fraction_of_lit"), ph.get("decoded_fraction_of_lit"))
        if v is not None
    ]
    if decoded:  # the phase maps the pixels a coarse camera's Gray code cannot
        found.append(
            _finding(
                "coverage",
                max(decoded),
                0.9,
                0.7,
                True,
                "fraction of the lit camera pixels whose projector position was decoded",
                "make the whole projected image visible and in focus, raise the exposure, and "
                "capture again",
            )
        )
    if gc.get("plane_agreement_min") is not None:
        found.append(
            _finding(
                "decode",
                gc["plane_agreement_min"],
                0.95,
                0.85,
                True,
                "the least agreement of a Gray-code plane with the chessboard's prediction",
                "the finest stripes are not resolved or the camera shook: focus the camera, "
                "raise the exposure, and capture again",
            )
        )
    mp = geo.get("map") or {}
    if mp.get("chessboard_rms_px") is not None:
        found.append(
            _finding(
                "geometry",
                mp["chessboard_rms_px"],
                0.5,
                1.0,
                False,
                "camera px RMS between the Gray-code map and the chessboard's corners",
                "fix the camera firmly (it moved or vibrated) and capture again",
            )
        )
    return found


def judge(cal: Calibration) -> Verdict:
    """The verdict on ``cal`` from its ``info["quality"]`` (exposure, noise, ramp residual:
    :func:`~viewcomp.calib.fit.quality.capture_quality`), its clipped pixels, the per-pixel
    lobe's residual against the noise, the camera-space geometry's statistics when present,
    and the paper's fit. A bundle written before these were measured is judged on what it
    has."""
    found = _capture_findings(cal) + _geometry_findings(cal.info.get("geometry") or {})
    paper_level = None
    if cal.paper is not None:
        r2 = float(np.min(cal.paper.fit.r2))
        found.append(
            _finding(
                "paper_fit",
                r2,
                0.6,
                0.4,
                True,
                "R^2 of the paper's Phong regression (least channel)",
                "the paper's method will compensate the highlight poorly here; prefer the "
                "per-pixel method (--method pixel, the default)",
                scope="paper method",
            )
        )
        paper_level = found[-1].level
    core = [f.level for f in found if f.scope == "calibration"]
    level = max(core, key=LEVELS.index) if core else "usable"
    return Verdict(level, paper_level, tuple(found))
