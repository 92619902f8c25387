"""HDR captures: bracketed 8- or 16-bit frames of one scene merged into one linear image.

A glossy screen's highlight is tens to hundreds of times its diffuse level: no single
exposure of an 8-bit camera holds both. The camera takes the same pattern at several relative
exposures (e.g. 1, 1/4, 1/16, 1/64, 1/256); :func:`merge_exposures` turns them into one float32
linear image in the units of a frame of relative exposure 1 (values above 1 are light that
such a frame would have clipped).

The merge is viewcomp's own weighted average (the scheme of Debevec and Malik 1997 with a
known response), not OpenCV's ``MergeDebevec`` (which wants 8-bit frames, exposure times in
seconds and its own response curve): each frame's codes are linearised by the camera's
response (:func:`~viewcomp.calib.io.imageio.to_linear`) and divided by the frame's relative
exposure; the frames are averaged per pixel-channel with the weight

    w_k = hat(z_k) * exposure_k,   hat(z) = max(0, min(z - BLACK_CODE, CLIP_CODE - z))

and no weight for a frame whose own code is clipped (>= CLIP_CODE, 250/255). hat is Debevec's
hat on the encoded value z in 0..1, zero for near-black codes (<= BLACK_CODE, 2/255), times
the exposure because a longer frame carries the same light with less relative noise. z_k is
the code frame k *should* hold, encode(reference * exposure_k), with the reference the longest
exposure not clipped there, rather than the frame's own code: in a dark region the short
frames' codes are mostly read noise, and weighing them by their own code would select the
noise that lifts them above black (measured: spikes of 100x the true level). A pixel-channel
no frame weighs takes the reference: the longest exposure not clipped (near black
everywhere), or, clipped in every frame, the shortest exposure's value, flagged in the
returned mask (the true value is at least that).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from viewcomp.calib.io.imageio import to_linear
from viewcomp.calib.world.response import Response, parse_response

#: Encoded value (0..1) from which a code counts as clipped: no weight in the merge.
CLIP_CODE = 250.0 / 255.0
#: Encoded value (0..1) up to which a code counts as near black: no weight in the merge.
BLACK_CODE = 2.0 / 255.0
#: The default relative exposures of a bracket: 2 stops apart over 8 stops.
DEFAULT_STOPS: tuple[float, ...] = (1.0, 1 / 4, 1 / 16, 1 / 64, 1 / 256)


def check_stops(stops: Sequence[float]) -> tuple[float, ...]:
    """Relative exposures as a tuple, checked: at least one, each finite and > 0, no repeats.

    Raises:
        ValueError: naming the bad value and what is expected.
    """
    out = tuple(float(s) for s in stops)
    if not out:
        raise ValueError("an HDR bracket needs at least one relative exposure")
    bad = [s for s in out if not (math.isfinite(s) and s > 0)]
    if bad:
        raise ValueError(f"relative exposures must be finite and > 0, got {bad[0]!r}")
    if len(set(out)) != len(out):
        raise ValueError(f"relative exposures must differ from each other, got {out}")
    return out


def merge_exposures(
    frames: Sequence[np.ndarray],
    exposures: Sequence[float],
    response: Response | str | float,
) -> tuple[np.ndarray, np.ndarray]:
    """Merge bracketed captures of one scene into linear light (see the module doc).

    Args:
        frames: K >= 1 encoded camera images, each (H, W, 3) uint8 or uint16, one size and
            dtype for all.
        exposures: K relative exposures (> 0, e.g. 1, 1/4, ...): frame k was taken with
            ``exposures[k]`` times the light of a frame of relative exposure 1.
        response: the camera's response (a :class:`Response` or a rig.toml value).

    Returns:
        ``(linear, clipped)``: linear (H, W, 3) float32 >= 0, light in the units of a frame of
        relative exposure 1 (0..1 is what that frame holds; more is what it would clip);
        clipped (H, W, 3) bool, the pixel-channels clipped in every frame (their value is the
        shortest exposure's, a lower bound).

    Raises:
        ValueError: no frames, a count of exposures that does not match, a bad exposure, or
            frames that are not uint8/uint16 (H, W, 3) of one size and dtype.
    """
    stops = check_stops(exposures)
    if len(frames) != len(stops):
        raise ValueError(f"merge_exposures: {len(frames)} frame(s) but {len(stops)} exposure(s)")
    first = np.asarray(frames[0])
    if first.ndim != 3 or first.shape[2] != 3 or first.dtype not in (np.uint8, np.uint16):
        raise ValueError(
            f"merge_exposures: frames must be (H, W, 3) uint8 or uint16 encoded codes, got "
            f"{first.shape} {first.dtype}"
        )
    for k, f in enumerate(frames):
        a = np.asarray(f)
        if a.shape != first.shape or a.dtype != first.dtype:
            raise ValueError(
                f"merge_exposures: frame {k} is {a.shape} {a.dtype}, frame 0 is {first.shape} "
                f"{first.dtype}: all frames must have one size and dtype"
            )
    resp = response if isinstance(response, Response) else parse_response(response)
    top = float(np.iinfo(first.dtype).max)
    lins = [
        to_linear(np.asarray(f), resp).astype(np.float64) / s
        for f, s in zip(frames, stops, strict=True)
    ]
    clips = [np.asarray(f) >= CLIP_CODE * top for f in frames]
    order = [int(k) for k in np.argsort(stops)]  # shortest first
    shortest = lins[order[0]]
    # the longest exposure not clipped at each pixel-channel: the reference
    reference = shortest.copy()
    clipped_all = np.ones(first.shape, bool)
    for k in order:
        reference = np.where(clips[k], reference, lins[k])
        clipped_all &= clips[k]
    total = np.zeros(first.shape, np.float64)
    weight = np.zeros(first.shape, np.float64)
    for k in order:
        # the hat of the code the reference predicts in frame k (not of the frame's own noisy
        # code: weighing dark frames by their own code would favour noise that lifts them)
        z = resp.encode(np.clip(reference * stops[k], 0.0, 1.0).astype(np.float32))
        w = np.maximum(0.0, np.minimum(z - BLACK_CODE, CLIP_CODE - z)) * stops[k]
        w = np.where(clips[k], 0.0, w)
        total += w * lins[k]
        weight += w
    out = np.where(weight > 0, total / np.where(weight > 0, weight, 1.0), reference)
    out = np.where(clipped_all, shortest, out)
    return np.maximum(out, 0.0).astype(np.float32), clipped_all
