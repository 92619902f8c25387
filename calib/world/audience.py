"""An audience: several viewers at once, each an eye position with a weight (docs/MODEL.md
section 6).

The compensation for an audience asks, per pixel, for the projector light y minimising
sum_k w_k |M_k y + A_k - T|^2 (:func:`viewcomp.calib.model.reference.audience_solve`); one
viewer is today's compensation for one eye. This module holds the viewers and reads them
from the command line's ``--audience SPEC``:

- ``60:120`` - a zone: :data:`ZONE_VIEWERS` viewers at angles spread evenly over 60..120
  degrees (both ends included); ``60:120:13`` - 13 of them;
- ``75`` - one viewer at 75 degrees; ``0.2,0.03,0.5`` - one at that eye position (metres);
- items separated by ``;`` (or spaces): ``"60;90;120"``, ``"0.2,0.03,0.5;-0.2,0.03,0.5"``;
- ``@W`` after an item weighs it (default 1; a zone's weight is shared by its viewers):
  ``"90@2;60;120"``.

Angles use the rig's viewer distance and height (E = (d cos t, h, d sin t)); every angle
and eye is checked as ``--angle``/``--eye`` are (:mod:`viewcomp.calib.world.eye`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from viewcomp.calib.errors import AudienceError
from viewcomp.calib.world.eye import EyeError, check_angle, check_eye, eye_from_angle, eye_to_polar

MAX_VIEWERS = 16  # viewers in one audience (the shader's loop bound)
ZONE_VIEWERS = 7  # viewers of a zone A:B without a count (every 10 degrees over 60:120)
_SPEC_HELP = (
    "give a zone A:B[:N] (degrees), angles or X,Y,Z eyes separated by ';', each optionally "
    'weighted with @W, e.g. 60:120, "60;90;120" or "0.2,0.03,0.5;-0.2,0.03,0.5"'
)


@dataclass(frozen=True, eq=False)
class Audience:
    """Viewers: ``eyes`` (K, 3) float64 metres and ``weights`` (K,) float64, positive, summing
    to 1 (normalised on construction), 1 <= K <= :data:`MAX_VIEWERS`.

    Raises:
        AudienceError: no viewers, too many, a bad eye, or weights not positive and finite.
    """

    eyes: np.ndarray
    weights: np.ndarray

    def __post_init__(self) -> None:
        e = np.asarray(self.eyes, np.float64)
        if e.ndim == 1:
            e = e.reshape(1, -1)
        if e.ndim != 2 or e.shape[1] != 3 or not 1 <= len(e) <= MAX_VIEWERS:
            raise AudienceError(
                f"an audience is 1 to {MAX_VIEWERS} eyes (K, 3), got shape {np.shape(self.eyes)}"
            )
        for i, eye in enumerate(e):
            check_eye(eye, f"viewer {i + 1}'s eye")
        w = np.asarray(self.weights, np.float64).reshape(-1)
        if w.shape != (len(e),) or not np.all(np.isfinite(w)) or np.any(w <= 0):
            raise AudienceError(
                f"an audience needs one positive, finite weight per viewer ({len(e)}), got "
                f"{np.asarray(self.weights).tolist()!r:.80}"
            )
        object.__setattr__(self, "eyes", e)
        object.__setattr__(self, "weights", w / w.sum())

    @classmethod
    def of(cls, view: Audience | np.ndarray | Sequence[float]) -> Audience:
        """An audience from an :class:`Audience` (itself), one eye (3,) or eyes (K, 3) of equal
        weights."""
        if isinstance(view, Audience):
            return view
        e = np.atleast_2d(np.asarray(view, np.float64))
        return cls(e, np.ones(len(e)))

    def __len__(self) -> int:
        return int(self.eyes.shape[0])

    @property
    def key(self) -> tuple[float, ...]:
        """Eyes and weights as one flat tuple: equal keys, equal audiences (for caches)."""
        return tuple(self.eyes.ravel().tolist()) + tuple(self.weights.tolist())

    @property
    def centre(self) -> np.ndarray:
        """The weighted mean eye (3,) metres (what a single-eye display reports)."""
        return np.asarray(self.weights @ self.eyes, np.float64)


def zone(lo: float, hi: float, n: int, distance: float, height: float) -> Audience:
    """``n`` viewers at angles spread evenly over [lo, hi] degrees (ends included; one viewer:
    the middle), equal weights, at ``distance`` and ``height`` metres."""
    lo = check_angle(lo, "the zone's first angle")
    hi = check_angle(hi, "the zone's last angle")
    if not 1 <= int(n) <= MAX_VIEWERS:
        raise AudienceError(f"a zone has 1 to {MAX_VIEWERS} viewers, got {n}")
    angles = np.linspace(lo, hi, int(n)) if n > 1 else np.array([(lo + hi) / 2.0])
    eyes = np.stack([eye_from_angle(a, distance, height) for a in angles])
    return Audience(eyes, np.ones(len(eyes)))


def zone_angles(audience: Audience) -> np.ndarray:
    """Each viewer's angle in degrees (:func:`~viewcomp.calib.world.eye.eye_to_polar`), (K,)."""
    return np.array([eye_to_polar(e)[0] for e in audience.eyes])


def _number(text: str, item: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise AudienceError(f"--audience: {item!r} is not a number; {_SPEC_HELP}") from None
    if not math.isfinite(v):
        raise AudienceError(f"--audience: {item!r} is not a finite number; {_SPEC_HELP}")
    return v


def parse_audience(spec: str, distance: float, height: float) -> Audience:
    """The viewers of an ``--audience`` SPEC (see the module docstring).

    Args:
        spec: the SPEC text.
        distance, height: the rig's viewer distance and eye height (metres), for angles.

    Raises:
        AudienceError: an empty or malformed SPEC, an angle or eye outside the limits, more
            than :data:`MAX_VIEWERS` viewers; the message names the item.
    """
    items = [s for s in spec.replace(";", " ").split() if s]
    if not items:
        raise AudienceError(f"--audience is empty; {_SPEC_HELP}")
    eyes: list[np.ndarray] = []
    weights: list[float] = []
    for item in items:
        body, _, wtext = item.partition("@")
        weight = _number(wtext, item) if wtext else 1.0
        if not weight > 0:
            raise AudienceError(f"--audience: the weight in {item!r} must be positive")
        try:
            if ":" in body:
                parts = body.split(":")
                if len(parts) not in (2, 3):
                    raise AudienceError(f"--audience: a zone is A:B or A:B:N, got {item!r}")
                n = ZONE_VIEWERS if len(parts) == 2 else _number(parts[2], item)
                if n != int(n):
                    raise AudienceError(f"--audience: a zone's count is whole, got {item!r}")
                z = zone(_number(parts[0], item), _number(parts[1], item), int(n), distance, height)
                eyes.extend(z.eyes)
                weights.extend([weight / len(z)] * len(z))
            elif "," in body:
                nums = [_number(p, item) for p in body.split(",")]
                if len(nums) != 3:
                    raise AudienceError(
                        f"--audience: an eye is X,Y,Z (three numbers), got {item!r}; to list "
                        "angles separate them with ';'"
                    )
                try:
                    eyes.append(check_eye(nums, f"the eye {body}"))
                except EyeError as exc:
                    raise AudienceError(
                        f"--audience: {exc} (to list angles, separate them with ';')"
                    ) from None
                weights.append(weight)
            else:
                angle = check_angle(_number(body, item), f"the angle {body}")
                eyes.append(eye_from_angle(angle, distance, height))
                weights.append(weight)
        except AudienceError:
            raise
        except EyeError as exc:
            raise AudienceError(f"--audience: {exc}") from None
        if len(eyes) > MAX_VIEWERS:
            raise AudienceError(
                f"--audience: more than {MAX_VIEWERS} viewers ({spec!r:.60}); use fewer"
            )
    return Audience(np.stack(eyes), np.asarray(weights))
