"""Eye tracks: where the viewer is at time t, as a callable ``t_seconds -> eye (3,)``.

A track is any callable returning the eye position (3,) float32 in metres (world frame of
docs/MODEL.md) for a presentation time in seconds, or an
:class:`~viewcomp.calib.world.audience.Audience` of several viewers. Angles use
E = (d cos t, h, d sin t).
"""

from __future__ import annotations

import csv
import os
from collections.abc import Callable
from pathlib import Path

import numpy as np

from viewcomp.calib.errors import TrackError
from viewcomp.calib.io.paths import check_input_file
from viewcomp.calib.world.audience import Audience
from viewcomp.calib.world.eye import check_angle, check_track, eye_from_angle

EyeTrack = Callable[[float], "np.ndarray | Audience"]


def constant_eye(x: float, y: float, z: float) -> EyeTrack:
    """A track that stays at eye (x, y, z) metres."""
    eye = np.array([x, y, z], np.float32)
    return lambda t: eye


def constant_audience(audience: Audience) -> EyeTrack:
    """A track that stays with one audience (several viewers, docs/MODEL.md section 6)."""
    return lambda t: audience


def constant_angle(deg: float, distance: float, height: float) -> EyeTrack:
    """A track at a fixed viewing angle (degrees), distance and height (metres)."""
    eye = eye_from_angle(deg, distance, height)
    return lambda t: eye


class AngleTrack:
    """Viewing angle interpolated linearly in time from (seconds, degrees) samples.

    Before the first sample the first angle holds, after the last the last one.
    """

    def __init__(self, times: np.ndarray, degrees: np.ndarray, distance: float, height: float):
        self.times, self.degrees = check_track(times, degrees, error=TrackError)
        self.distance, self.height = float(distance), float(height)

    def angle(self, t: float) -> float:
        """Viewing angle in degrees at time ``t`` seconds."""
        return float(np.interp(t, self.times, self.degrees))

    def __call__(self, t: float) -> np.ndarray:
        return eye_from_angle(self.angle(t), self.distance, self.height)


def load_angle_track(path: str | os.PathLike[str], distance: float, height: float) -> AngleTrack:
    """Read a CSV of ``seconds,degrees`` rows into an :class:`AngleTrack`.

    An optional header row (non-numeric first field), blank lines and lines starting with
    ``#`` are skipped. Times must be strictly increasing; angles in degrees (90 = in front).

    Raises:
        TrackError: unreadable file, wrong column count, non-numbers, non-increasing times.
    """
    path = Path(path)
    check_input_file(path, "angle track", "a CSV of `seconds,degrees` rows", TrackError)
    fix = "fix: write one `seconds,degrees` pair per line, times increasing, e.g. `0,90`"
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise TrackError(f"cannot read angle track {path}: {exc}") from exc
    times: list[float] = []
    degrees: list[float] = []
    for lineno, row in enumerate(csv.reader(text.splitlines()), start=1):
        if not row or not "".join(row).strip() or row[0].lstrip().startswith("#"):
            continue
        if len(row) != 2:
            raise TrackError(f"{path}:{lineno}: expected 2 columns, got {len(row)}; {fix}")
        try:
            t, d = float(row[0]), float(row[1])
        except ValueError as exc:
            if not times and lineno == 1:
                continue  # a header row
            raise TrackError(f"{path}:{lineno}: not a number ({row}); {fix}") from exc
        if not (np.isfinite(t) and np.isfinite(d)):
            raise TrackError(f"{path}:{lineno}: not a finite number ({row}); {fix}")
        check_angle(d, f"{path}:{lineno}: the angle", TrackError)
        if times and t <= times[-1]:
            raise TrackError(f"{path}:{lineno}: time {t} is not after {times[-1]}; {fix}")
        times.append(t)
        degrees.append(d)
    if not times:
        raise TrackError(f"{path}: no (seconds, degrees) rows; {fix}")
    return AngleTrack(np.array(times), np.array(degrees), distance, height)
