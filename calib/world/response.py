"""Camera response curves: encoded pixel value <-> linear light.

A camera stores *encoded* values; the math of docs/MODEL.md needs *linear* light. Both sides are
normalised to 0..1 here: encoded 0..1 is the pixel code divided by its full scale (255 or
65535), linear 0..1 is light in the camera's units (1 = the light that reaches full scale).

The four responses of ``[camera] response`` in rig.toml (docs/INTERFACES.md):

- ``"linear"``: value = linear.
- ``"srgb"``: the IEC 61966-2-1 sRGB transfer function (linear segment near black, then a
  2.4 power with offset).
- a number ``g`` > 0: value = linear^(1/g) (a pure power law; ``g = 2.2`` is the classic video
  gamma, ``g = 1`` is the same as ``"linear"``).
- an array of N >= 2 numbers: a table, the linear light at encoded values k / (N - 1)
  (k = 0 .. N-1), strictly increasing from 0 to 1, linear between entries: what `capture --hdr`
  writes when a camera's curve (a webcam's S-shaped tone curve) fits neither model
  (:mod:`viewcomp.calib.hw.hdrresponse`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

ResponseKind = Literal["linear", "srgb", "gamma", "table"]

ALLOWED = (
    '"linear", "srgb", a positive number g (meaning value = linear^(1/g)) or an array of '
    "linear light at evenly spaced encoded values, 0 to 1"
)
#: Entries a response table may have: 2 .. one per 16-bit code.
TABLE_MAX = 65536

# sRGB constants (IEC 61966-2-1). The encode threshold is the decode threshold mapped through
# the linear segment, so the two branches switch at the same point.
_SRGB_A = 0.055
_SRGB_GAMMA = 2.4
_SRGB_SLOPE = 12.92
_SRGB_DECODE_KNEE = 0.04045
_SRGB_ENCODE_KNEE = _SRGB_DECODE_KNEE / _SRGB_SLOPE


@dataclass(frozen=True)
class Response:
    """A camera response curve. Build one with :func:`parse_response`.

    ``kind`` is ``"linear"``, ``"srgb"``, ``"gamma"`` or ``"table"``; ``gamma`` is the
    exponent g of the power law (1.0 for the other kinds); ``table`` a table's entries (the
    linear light at encoded values k / (N - 1); empty for the other kinds). Both methods take
    arrays of any shape and return float32 (computed in float64); inputs are clipped to 0..1
    first (a camera cannot encode light beyond its full scale, and noise can push linear
    values slightly below 0).
    """

    kind: ResponseKind
    gamma: float = 1.0
    table: tuple[float, ...] = ()

    @property
    def spec(self) -> str | float | tuple[float, ...]:
        """The rig.toml value that describes this response: ``"linear"``, ``"srgb"``, g or the
        table's entries."""
        if self.kind == "table":
            return self.table
        return self.gamma if self.kind == "gamma" else self.kind

    def decode(self, encoded01: np.ndarray) -> np.ndarray:
        """Encoded 0..1 (pixel code / full scale) -> linear 0..1. Same shape, float32."""
        e = np.clip(np.asarray(encoded01, dtype=np.float64), 0.0, 1.0)
        if self.kind == "table":
            t = np.asarray(self.table, np.float64)
            e = np.interp(e, np.linspace(0.0, 1.0, t.size), t)
        elif self.kind == "gamma":
            e = np.power(e, self.gamma)
        elif self.kind == "srgb":
            e = np.where(
                e <= _SRGB_DECODE_KNEE,
                e / _SRGB_SLOPE,
                np.power((e + _SRGB_A) / (1.0 + _SRGB_A), _SRGB_GAMMA),
            )
        return np.clip(e, 0.0, 1.0).astype(np.float32)

    def encode(self, linear01: np.ndarray) -> np.ndarray:
        """Linear 0..1 -> encoded 0..1 (multiply by 255 or 65535 for codes). Float32."""
        x = np.clip(np.asarray(linear01, dtype=np.float64), 0.0, 1.0)
        if self.kind == "table":
            t = np.asarray(self.table, np.float64)
            x = np.interp(x, t, np.linspace(0.0, 1.0, t.size))
        elif self.kind == "gamma":
            x = np.power(x, 1.0 / self.gamma)
        elif self.kind == "srgb":
            x = np.where(
                x <= _SRGB_ENCODE_KNEE,
                x * _SRGB_SLOPE,
                (1.0 + _SRGB_A) * np.power(x, 1.0 / _SRGB_GAMMA) - _SRGB_A,
            )
        return np.clip(x, 0.0, 1.0).astype(np.float32)


def parse_response(spec: str | float | Sequence[float]) -> Response:
    """The response named by a rig.toml ``response`` value.

    ``spec`` is ``"linear"``, ``"srgb"`` (case-insensitive), a positive finite number g,
    given as a number or as a numeric string (``"2.2"``), or a table (a list or tuple of
    numbers, module doc). Raises ``ValueError`` naming the allowed values otherwise.
    """
    if isinstance(spec, list | tuple):
        return _table(spec)
    if isinstance(spec, bool):
        raise ValueError(f"unknown camera response {spec!r}: expected {ALLOWED}")
    if isinstance(spec, str):
        name = spec.strip().lower()
        if name in ("linear", "srgb"):
            return Response(kind=name)  # type: ignore[arg-type]
        try:
            value = float(name)
        except ValueError:
            raise ValueError(f"unknown camera response {spec!r}: expected {ALLOWED}") from None
    elif isinstance(spec, int | float):
        value = float(spec)
    else:
        raise ValueError(
            f"unknown camera response {spec!r} ({type(spec).__name__}): expected {ALLOWED}"
        )
    if not math.isfinite(value) or value <= 0.0:
        raise ValueError(f"camera response gamma must be a positive finite number, got {spec!r}")
    return Response(kind="gamma", gamma=value)


def _table(spec: Sequence[object]) -> Response:
    """A table response from its entries (module doc); ValueError naming what is wrong."""
    n = len(spec)
    if not 2 <= n <= TABLE_MAX:
        raise ValueError(f"a camera response table has 2 to {TABLE_MAX} entries, got {n}")
    if any(isinstance(v, bool) or not isinstance(v, int | float) for v in spec):
        raise ValueError("a camera response table holds numbers only")
    t = np.asarray(spec, np.float64)
    if not np.all(np.isfinite(t)):
        raise ValueError("a camera response table holds finite numbers only")
    if t[0] != 0.0 or t[-1] != 1.0:
        raise ValueError(
            f"a camera response table goes from 0 (black) to 1 (full scale), got {t[0]:g} .. "
            f"{t[-1]:g}"
        )
    if np.any(np.diff(t) <= 0):
        k = int(np.argmax(np.diff(t) <= 0))
        raise ValueError(
            f"a camera response table must increase at every entry (entry {k + 1} is "
            f"{t[k + 1]:g} after {t[k]:g})"
        )
    return Response(kind="table", table=tuple(float(v) for v in t))


def table_lines(
    name: str, table: Sequence[float], comment: str, fmt: Callable[[float], str]
) -> list[str]:
    """A table as the lines of a TOML array ``name`` in rig.toml: the opening line with its
    ``comment``, the entries 8 a line, each written by ``fmt`` (the rig writer's own value
    formatter), and the closing bracket."""
    rows = [
        "    " + ", ".join(fmt(float(v)) for v in table[k : k + 8]) + ","
        for k in range(0, len(table), 8)
    ]
    return [f"{name + ' = [':<40} # {comment}", *rows, "]"]
