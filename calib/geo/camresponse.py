"""The camera's response, estimated from light's additivity in the Gray-code pairs.

A Gray-code plane and its inverse, linearised, must sum to white + black even where the
optics blur a stripe edge to an intermediate value; the response ("linear", "srgb" or a power
law) that makes them do so is the camera's. A rig response that misfits grossly is refused.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from viewcomp.calib.errors import FitError
from viewcomp.calib.geo.captures import Captures
from viewcomp.calib.geo.graycode import GrayCode, decode_graycode
from viewcomp.calib.io.captureset import CaptureSet
from viewcomp.calib.world.response import Response, parse_response

RESPONSE_GAMMAS = (1.0, 3.5)  # the range of power laws tried
RESPONSE_REFUSE = (0.05, 4.0)  # refuse the rig's response above this misfit and ratio to best


def response_misfit(codes: np.ndarray, response: Response) -> float:
    """How badly ``response`` linearises complementary captures: RMS of
    (L(P) + L(P') - L(W) - L(B)) / (L(W) - L(B)) over the samples.

    ``codes`` (N, 4, 3) encoded 0..1 values of a Gray-code plane P, its inverse P', white W
    and black B at the same pixels. Light adds: where the optics blur a stripe edge, a camera
    pixel gets a share a of the lit side in P and 1 - a in P', so in linear units
    L(P) + L(P') = L(W) + L(B) for any a. Only the true response makes the sum hold at
    intermediate values.
    """
    lin = response.decode(codes).astype(np.float64)
    span = lin[:, 2] - lin[:, 3]
    ok = span > 0.05
    if not np.any(ok):
        return float("nan")
    err = (lin[:, 0] + lin[:, 1] - lin[:, 2] - lin[:, 3])[ok] / span[ok]
    return float(np.sqrt(np.mean(err**2)))


def estimate_response(codes: np.ndarray) -> tuple[Response, float]:
    """The response among "linear", "srgb" and power laws g in :data:`RESPONSE_GAMMAS` that
    best satisfies additivity (:func:`response_misfit`); returns it and its misfit.

    An estimate for cameras that do nothing non-linear to neighbouring pixels (in-camera
    sharpening or local tone mapping break additivity: switch them off).
    """
    from scipy.optimize import minimize_scalar

    if len(codes) < 100:
        raise ValueError(f"too few stripe-edge samples to estimate a response ({len(codes)})")
    found = minimize_scalar(
        lambda g: response_misfit(codes, parse_response(float(g))),
        bounds=RESPONSE_GAMMAS,
        method="bounded",
        options={"xatol": 1e-3},
    )
    cands = [
        (parse_response("linear"), response_misfit(codes, parse_response("linear"))),
        (parse_response("srgb"), response_misfit(codes, parse_response("srgb"))),
        (parse_response(round(float(found.x), 2)), float(found.fun)),
    ]
    return min(cands, key=lambda c: c[1])


def estimate_set_response(cs: CaptureSet) -> tuple[Response, float]:
    """:func:`estimate_response` from a camera-space set's Gray-code captures (screen/).

    Raises:
        FitError: Gray-code captures missing or the projector not visible.
        ValueError: too few stripe-edge pixels (a blur-free or tiny image).
    """
    caps = Captures(cs, "screen")
    gc = decode_graycode(caps, cs.rig.projector.resolution)
    return estimate_response(caps.response.encode(gc.response_samples))


def check_response(gc: GrayCode, response: Response, where: str) -> dict[str, Any]:
    """Compare the rig's response with the best estimate from the Gray-code pairs; refuse a
    rig response that misfits grossly. Returns the statistics."""
    codes = response.encode(gc.response_samples)
    if len(codes) < 100:
        return {"rig": response.spec, "samples": len(codes)}
    rig_misfit = response_misfit(codes, response)
    best, best_misfit = estimate_response(codes)
    out = {
        "rig": response.spec,
        "rig_misfit": round(rig_misfit, 4),
        "estimated": best.spec,
        "estimated_misfit": round(best_misfit, 4),
        "samples": len(codes),
    }
    limit, ratio = RESPONSE_REFUSE
    if rig_misfit > limit and rig_misfit > ratio * best_misfit:
        raise FitError(
            where,
            f"[camera] response = {response.spec!r} does not linearise the captures: "
            f"complementary Gray-code captures do not add up (misfit {rig_misfit:.3f}), while "
            f"response = {best.spec!r} fits ({best_misfit:.3f}); set it in rig.toml, or switch "
            "off the camera's sharpening and tone mapping if it has them",
        )
    return out
