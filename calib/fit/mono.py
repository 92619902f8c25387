"""A mono camera's captures in the per-primary basis, so that both methods fit them
(docs/MODEL.md, "Mono cameras").

A mono camera measures one number per pixel: its luminance Y. It cannot see colour, but it
can see each projector primary shown alone: the set of a mono camera holds, beside Table 1,
each primary alone at the gray level (``red_alone`` = (110, 0, 0), ...) and alone on the ramp
(``ramp_red``, ...) (:func:`~viewcomp.calib.io.patterns.primary_patterns`). In the basis whose
channel j is "the light of projector primary j, as the camera sees it", the screen mixes no
primaries (W~ = I), and every Table 1 capture is made from the mono ones, light adding up:

    E_j(x)          = Y[j_alone](x) - Y[black](x)          primary j at 110, above black
    black_j         = A(x) / 3,  A = Y[black]               ambient and leak, shared evenly
    gray_j          = E_j + A / 3
    red/green/blue  = gray, plus Y[pattern] - Y[gray] in the pattern's own channel
    ramp_j          = Y[ramp_j] - A + A / 3

What this assumes: the surface's colour is seen only through the three primaries' per-pixel
gains (a surface that shifts a primary's light toward another's hue is not seen), and the
primaries do not mix on the surface (cross-talk zero). Light adds up: the mono gray equals
black plus the three primaries' E_j; how far it does not is measured
(``additivity``: RMS of Y[gray] - (A + sum E_j) over the lit pixels, relative to their mean).
"""

from __future__ import annotations

import numpy as np

from viewcomp.calib.errors import FitError
from viewcomp.calib.io.patterns import PRIMARY_PATTERNS

COLOURS = ("red", "green", "blue")


def _y(image: np.ndarray) -> np.ndarray:
    """A mono capture (H, W, 3) with equal channels -> (H, W) float64 luminance."""
    return np.asarray(image, np.float64).mean(axis=2)


def per_primary_images(
    images: dict[str, np.ndarray], sub: str
) -> tuple[dict[str, np.ndarray], float]:
    """One stage's mono captures (name -> (H, W, 3) linear, R = G = B, on the projector grid;
    Table 1 with black, and :data:`PRIMARY_PATTERNS`) as per-primary (H, W, 3) float32
    captures of Table 1 (module doc); and the additivity misfit (relative RMS).

    Raises:
        FitError: a per-primary capture or black is missing (a set from a capture without
            them: capture it again), or a primary alone is not brighter than black.
    """
    missing = [n for n in ("black", *PRIMARY_PATTERNS) if n not in images]
    if missing:
        raise FitError(
            f"{sub}/{missing[0]}",
            "missing from a mono camera's set: its fits need each projector primary alone "
            "and black (the per-primary patterns `viewcomp capture` takes with a mono camera); "
            "capture the set again",
        )
    a = _y(images["black"])
    e = np.stack([_y(images[f"{c}_alone"]) - a for c in COLOURS], axis=-1)
    lit = _y(images["gray"]) - a > 0.1 * np.percentile(_y(images["gray"]) - a, 99)
    for j, c in enumerate(COLOURS):
        if not np.median(e[..., j][lit]) > 0:
            raise FitError(
                f"{sub}/{c}_alone",
                f"not brighter than {sub}/black where the projector lights the screen: check "
                "that the projector shows the primaries and capture the set again",
            )
    third = (a / 3.0)[..., None]
    gray = e + third
    out = {"black": np.repeat(third, 3, axis=2), "gray": gray}
    for j, c in enumerate(COLOURS):
        img = gray.copy()
        img[..., j] += _y(images[c]) - _y(images["gray"])
        out[c] = img
    out["ramp"] = np.stack([_y(images[f"ramp_{c}"]) - a for c in COLOURS], axis=-1) + third
    resid = (_y(images["gray"]) - a - e.sum(axis=-1))[lit]
    level = float(np.mean((_y(images["gray"]) - a)[lit]))
    additivity = float(np.sqrt(np.mean(resid**2)) / max(level, 1e-12))
    return {k: v.astype(np.float32) for k, v in out.items()}, additivity
