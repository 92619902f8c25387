"""Faults the emulator injects, and their text form for the command line.

Counting conventions (both 0-based):

- *show index* K: the K-th call of ``projector.show()`` is index K (the first is 0);
- *grab index* G: the G-th call of ``camera.grab()`` is index G (the first is 0), failed
  calls included.

Faults:

- ``bump_at = (K, PX)``: the camera is bumped at the swap of show index K: every frame whose
  exposure starts at or after that swap sees the camera's pose shifted so that the screen
  moves about PX camera pixels to the left in the image (PX < 0: to the right); frames
  exposed earlier (still in a driver queue) are unaffected;
- ``drop_at`` / ``drop_p``: at these grab indices (or with this probability per grab) the
  driver loses the frame it was about to deliver: grab returns the next one, with a gap in
  :attr:`Frame.sequence`;
- ``fail_at`` / ``fail_p``: at these grab indices (or with this probability) grab raises
  :class:`~viewcomp.calib.hw.interface.FrameError` (the frame is lost, the device goes on);
- ``late_at`` / ``late_p``: at these show indices (or with this probability) the light
  changes one refresh later than the projector's usual latency.

Text form (:func:`parse_faults`): items separated by commas, ``bump=K:PX``,
``drop=G[+G...]``, ``fail=G[+G...]``, ``late=K[+K...]``, ``drop_p=P``, ``fail_p=P``,
``late_p=P``; e.g. ``"bump=20:3,fail=5+9,late_p=0.05"``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np


class FaultSpecError(ValueError):
    """A fault specification that cannot be used; the message names the item and the fix."""


@dataclass(frozen=True)
class Faults:
    """The faults to inject (see the module doc for the meaning and the counting)."""

    bump_at: tuple[int, float] | None = None
    drop_at: tuple[int, ...] = ()
    fail_at: tuple[int, ...] = ()
    late_at: tuple[int, ...] = ()
    drop_p: float = 0.0
    fail_p: float = 0.0
    late_p: float = 0.0

    def __post_init__(self) -> None:
        for name in ("drop_p", "fail_p", "late_p"):
            v = getattr(self, name)
            if not (math.isfinite(v) and 0.0 <= v <= 1.0):
                raise FaultSpecError(f"{name} is a probability in 0..1, got {v}")
        for name in ("drop_at", "fail_at", "late_at"):
            if any(int(i) < 0 for i in getattr(self, name)):
                raise FaultSpecError(
                    f"{name} holds 0-based indices >= 0, got {getattr(self, name)}"
                )
        if self.bump_at is not None:
            k, px = self.bump_at
            if int(k) < 0 or not math.isfinite(px):
                raise FaultSpecError(
                    f"bump_at is (show index K >= 0, camera pixels), got {self.bump_at}"
                )

    def is_late(self, show: int, rng: np.random.Generator) -> bool:
        """Whether show index ``show`` lights one refresh late (draws from ``rng`` only when
        ``late_p`` > 0)."""
        return show in self.late_at or (self.late_p > 0 and rng.random() < self.late_p)

    def drops(self, grab: int, rng: np.random.Generator) -> bool:
        """Whether grab index ``grab`` loses the frame it was about to deliver."""
        return grab in self.drop_at or (self.drop_p > 0 and rng.random() < self.drop_p)

    def fails(self, grab: int, rng: np.random.Generator) -> bool:
        """Whether grab index ``grab`` fails (FrameError)."""
        return grab in self.fail_at or (self.fail_p > 0 and rng.random() < self.fail_p)


def parse_bump(text: str) -> tuple[int, float]:
    """``"K:PX"`` -> (show index K, camera pixels PX).

    Raises:
        FaultSpecError: not two numbers K:PX with K a whole number >= 0.
    """
    try:
        k_text, px_text = text.split(":")
        k, px = int(k_text), float(px_text)
    except ValueError:
        raise FaultSpecError(
            f"a bump is K:PX (show index K >= 0, counted from 0, and camera pixels PX, e.g. "
            f"20:3), got {text!r}"
        ) from None
    if k < 0 or not math.isfinite(px):
        raise FaultSpecError(f"a bump is K:PX with K >= 0 and PX finite, got {text!r}")
    return (k, px)


def parse_faults(text: str) -> Faults:
    """The :class:`Faults` of a text specification (see the module doc); ``""`` is none.

    Raises:
        FaultSpecError: an unknown item or a malformed value (the message names it).
    """
    known = {f.name.removesuffix("_at") for f in fields(Faults)} | {"bump"}
    values: dict[str, object] = {}
    for item in (s.strip() for s in text.split(",")):
        if not item:
            continue
        name, sep, value = item.partition("=")
        name = name.strip().lower()
        if not sep or name not in known:
            raise FaultSpecError(
                f"unknown fault {item!r}: use bump=K:PX, drop=G+G, fail=G+G, late=K+K, "
                "drop_p=P, fail_p=P, late_p=P separated by commas"
            )
        try:
            if name == "bump":
                values["bump_at"] = parse_bump(value)
            elif name.endswith("_p"):
                values[name] = float(value)
            else:
                values[f"{name}_at"] = tuple(int(v) for v in value.split("+"))
        except ValueError as e:
            if isinstance(e, FaultSpecError):
                raise
            raise FaultSpecError(
                f"fault {item!r}: {name} takes "
                + ("a probability P in 0..1" if name.endswith("_p") else "indices G+G+...")
            ) from None
    return Faults(**values)  # type: ignore[arg-type]
