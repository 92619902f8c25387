"""Small helpers shared by the sub-commands: argument parsing and progress lines."""

from __future__ import annotations

import sys
import time

import numpy as np

from viewcomp.cli import UsageError


def parse_size(text: str) -> tuple[int, int]:
    """'WxH' -> (w, h), both positive."""
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise UsageError(f"a size is WIDTHxHEIGHT in pixels, e.g. 1280x720; got {text!r}") from None
    if w < 2 or h < 2:
        raise UsageError(f"a size needs at least 2x2 pixels, got {text!r}")
    return w, h


def parse_vec3(text: str, what: str = "an eye position") -> np.ndarray:
    """'X,Y,Z' -> (3,) float metres."""
    try:
        v = np.array([float(x) for x in text.split(",")])
    except ValueError:
        raise UsageError(f"{what} is X,Y,Z in metres, e.g. 0.1,0.0,0.5; got {text!r}") from None
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise UsageError(f"{what} is three numbers X,Y,Z in metres; got {text!r}")
    return v


def parse_rgb(text: str) -> tuple[float, float, float]:
    """'R,G,B' albedos in 0..1."""
    try:
        v = tuple(float(x) for x in text.split(","))
    except ValueError:
        raise UsageError(f"a screen colour is a name or R,G,B in 0..1; got {text!r}") from None
    if len(v) != 3:
        raise UsageError(f"a screen colour is a name or R,G,B in 0..1; got {text!r}")
    return v  # type: ignore[return-value]


class Log:
    """Progress lines on stderr with the elapsed time (quiet with ``quiet=True``)."""

    def __init__(self, quiet: bool = False) -> None:
        self.quiet = quiet
        self.t0 = time.perf_counter()

    def __call__(self, msg: str) -> None:
        if not self.quiet:
            print(f"[{time.perf_counter() - self.t0:6.1f} s] {msg}", file=sys.stderr, flush=True)
