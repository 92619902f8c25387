"""The camera's response estimated from an HDR bracket, for `capture --hdr` without a known
response: OpenCV's ``createCalibrateDebevec`` (Debevec and Malik 1997) recovers the curve
code -> relative light from 8-bit frames of one scene at known relative exposures.

Two candidates are made from it: the simpler model that fits it best in log light over codes
8..247 (:func:`fit_response`: ``"srgb"`` or a power law g, ``"linear"`` when g is within 0.05
of 1), and the curve itself as a table (:func:`response_table`). :func:`choose_response`
judges them by the bracket itself: a pixel well exposed in two stops must give the same light
through the right curve (:func:`stop_disagreement`), and the table is kept only where it
agrees clearly better (:data:`TABLE_GAIN`): a webcam's S-shaped tone curve is neither sRGB nor
a power law (measured on the emulated webcam: Debevec's curve within 3-6 % of its true curve
over codes 8..224, where the best power law is 10-20 % off), while a curve that one of the
models describes keeps the model, which noise does not bend.

Debevec's curve is poorly constrained where few pixels are well exposed in two stops: near
black and at the top codes (on the emulated webcam 16 % off at code 240, 54 % at 247), so the
table takes it over codes :data:`TABLE_LOW` .. :data:`TABLE_HIGH` and continues it below in
proportion to the code and above with its log-log slope over the codes just below. Within that
range its per-code noise is smoothed away by a polynomial of degree :data:`TABLE_DEGREE` in
log light: a camera's curve is smooth, and wiggles of a few per cent in it are local slope
errors that an HDR merge turns into errors between patterns taken from different stops.
Measured on the emulated webcam's HDR spectralon row (ratio to ideal captures at 60 / 125
degrees; table off the true curve over codes 32-224, RMS): Debevec's curve as it is 1.26 /
1.22 (2.2 %), degree 5 1.15 / 1.10 (1.0 %), degree 7 1.08 / 1.05 (1.2 %), degree 3 too stiff
to beat sRGB (1.42 / 1.33 with sRGB); the true curve 1.17 at 60 degrees (16 frames).
"""

from __future__ import annotations

import itertools

import numpy as np

from viewcomp.calib.world.response import Response, parse_response

CODES = np.arange(8, 248)
#: Codes over which a table follows Debevec's curve (module doc).
TABLE_LOW = 16
TABLE_HIGH = 224
#: Degree of the polynomial (in log light over the code) that smooths the table.
TABLE_DEGREE = 7
#: The table is kept when its stop disagreement is at most this share of the model's.
TABLE_GAIN = 0.8
#: Codes (8-bit) a pixel needs in both stops to count in their disagreement.
AGREE_CODES = (16, 235)


def debevec_curve(frames: list[np.ndarray], exposures: list[float]) -> np.ndarray:
    """(256,) relative light per 8-bit code (the mean of the channels' curves), from
    ``frames`` (each (H, W, 3) uint8 RGB of one scene) at relative ``exposures``."""
    import cv2

    if len(frames) < 2 or any(f.dtype != np.uint8 for f in frames):
        raise ValueError("the response estimate needs >= 2 uint8 frames")
    images = [np.ascontiguousarray(f[:, :, ::-1]) for f in frames]
    times = np.asarray(exposures, np.float32)
    curve = cv2.createCalibrateDebevec().process(images, times)
    return np.asarray(curve, np.float64).reshape(256, 3).mean(axis=1)


def fit_response(curve: np.ndarray) -> tuple[Response, float]:
    """The rig.toml response that fits ``curve`` (256,) best, and its RMS misfit in natural
    log light (the curve's unknown scale is fitted too)."""
    y = np.log(np.maximum(curve[CODES], 1e-12))
    x = CODES / 255.0
    # power law: log y = c + g log x
    lx = np.log(x)
    a = np.stack([np.ones_like(lx), lx], axis=1)
    (c, g), *_ = np.linalg.lstsq(a, y, rcond=None)
    gamma_rms = float(np.sqrt(np.mean((a @ np.array([c, g]) - y) ** 2)))
    srgb = np.log(np.maximum(parse_response("srgb").decode(x.astype(np.float32)), 1e-12))
    c_s = float(np.mean(y - srgb))
    srgb_rms = float(np.sqrt(np.mean((srgb + c_s - y) ** 2)))
    if srgb_rms < gamma_rms:
        return parse_response("srgb"), srgb_rms
    if abs(g - 1.0) < 0.05:
        return parse_response("linear"), gamma_rms
    return parse_response(round(float(g), 2)), gamma_rms


def response_table(curve: np.ndarray) -> Response:
    """Debevec's ``curve`` (256,) as a table response (module doc): entries at every 8-bit
    code, 0 at code 0 and 1 at 255, strictly increasing."""
    c = np.maximum(np.asarray(curve, np.float64), 1e-12)
    k = np.arange(256, dtype=np.float64)
    inside = k[TABLE_LOW : TABLE_HIGH + 1]
    smooth = np.polynomial.Polynomial.fit(
        inside, np.log(c[TABLE_LOW : TABLE_HIGH + 1]), TABLE_DEGREE
    )
    c[TABLE_LOW : TABLE_HIGH + 1] = np.exp(smooth(inside))
    y = c.copy()
    y[:TABLE_LOW] = c[TABLE_LOW] * k[:TABLE_LOW] / TABLE_LOW
    lo = TABLE_HIGH - 32
    slope = np.log(c[TABLE_HIGH] / c[lo]) / np.log(TABLE_HIGH / lo)
    # light grows at least in proportion to the code up there (a shoulder compresses it)
    y[TABLE_HIGH:] = c[TABLE_HIGH] * (k[TABLE_HIGH:] / TABLE_HIGH) ** max(slope, 1.0)
    y = np.maximum.accumulate(y) / y[255]
    y = y + 1e-6 * k / 255.0  # strictly increasing where the curve is flat
    y = (y - y[0]) / (y[255] - y[0])
    entries = [float(f"{v:.7g}") for v in y]
    entries[0], entries[-1] = 0.0, 1.0
    return parse_response(entries)


def stop_disagreement(frames: list[np.ndarray], exposures: list[float], resp: Response) -> float:
    """RMS (natural log) of the light two stops of the bracket give a pixel-channel through
    ``resp``, over the pixel-channels both stops hold at :data:`AGREE_CODES` (consecutive
    stops; ``frames`` (H, W, 3) uint8 at relative ``exposures``). inf when none are."""
    order = np.argsort(exposures)
    lo, hi = AGREE_CODES
    sq, n = 0.0, 0
    for a, b in itertools.pairwise(order):
        fa, fb = frames[a], frames[b]
        ok = (fa >= lo) & (fa <= hi) & (fb >= lo) & (fb <= hi)
        if not ok.any():
            continue
        la = resp.decode(fa[ok] / 255.0).astype(np.float64) / exposures[a]
        lb = resp.decode(fb[ok] / 255.0).astype(np.float64) / exposures[b]
        d = np.log(np.maximum(la, 1e-12) / np.maximum(lb, 1e-12))
        sq += float(np.sum(d**2))
        n += d.size
    return float(np.sqrt(sq / n)) if n else float("inf")


def choose_response(
    curve: np.ndarray, frames: list[np.ndarray], exposures: list[float]
) -> tuple[Response, str]:
    """The response to merge ``frames`` (each (H, W, 3) uint8, at relative ``exposures``)
    with, from their Debevec ``curve`` (module doc), and what was found, for the log."""
    model, misfit = fit_response(curve)
    table = response_table(curve)
    d_model = stop_disagreement(frames, exposures, model)
    d_table = stop_disagreement(frames, exposures, table)
    said = (
        f"the stops disagree by {d_model:.3f} in log light through {model.spec!r} (its misfit "
        f"to the curve {misfit:.3f}), by {d_table:.3f} through the curve as a table"
    )
    if d_table <= TABLE_GAIN * d_model:
        return table, "a table (Debevec's curve): " + said
    return model, f"{model.spec!r}: " + said
