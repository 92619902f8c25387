"""The frame's edge zone: the outer lines of rectified captures that the camera saw mixed with
the unlit surround, measured from the captures themselves.

A camera sees the projected frame's edge spread over a few of its pixels (the optics, the
pixel's area, demosaicking, in-camera denoising and sharpening) and, for an MJPEG stream,
colour spread further still (4:2:0 chroma is stored at half resolution, so a coloured screen's
edge loses its colour over about two camera pixels more than its brightness). On the projector
grid that is ``spread / density`` lines: one line for the simulator's camera (1.2 camera px per
projector px), five to ten for a 720p webcam on a 1080p projector (0.6). Those lines read what
the surround added, not what the screen reflects there: left in, they bias every per-pixel
term at the frame's edge and, through them, what the fits take from the edge (the lobe's
baseline at the farthest angles, the tone map's worst pixels).

:func:`edge_widths` measures, per side, how many lines step from their inner neighbour by
more than a screen's own shading does; :func:`fill_edge_zone` then gives every pixel of the
zone the value of the nearest pixel inside it. At a corner the camera mixes in the surround
from two sides, so the zone there is a square of twice the sides' widths (on the webcam
emulator's captures the corner pixel just inside the sides' zones reads 10-15 % dark).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

import numpy as np

#: A line is flat when it differs from the next line inward by at most this share of the
#: capture's brightest channel near the edge; the zone ends at the first two flat lines. A
#: screen's own shading (vignetting, the projector's fall-off, a broad sheen) changes by well
#: under 1 % a line; the edge's spread by 5-20 % a line, a webcam's sharpening halo and MJPEG
#: blocks by 1-3 %.
EDGE_TOL = 0.03
#: The widest edge zone measured (projector px).
EDGE_MAX = 16
#: Lines past the widest zone whose level scales the tolerance.
LEVEL_LINES = 8

SIDES = ("top", "bottom", "left", "right")


def _profiles(image: np.ndarray, depth: int) -> dict[str, np.ndarray]:
    """Per side, the median over the side's central half of each of its ``depth`` outermost
    lines, outermost first: (depth, C) per side."""
    h, w = image.shape[:2]
    img = image if image.ndim == 3 else image[..., None]
    rows = slice(h // 4, h - h // 4)
    cols = slice(w // 4, w - w // 4)
    return {
        "top": np.median(img[:depth, cols], axis=1),
        "bottom": np.median(img[::-1][:depth, cols], axis=1),
        "left": np.median(img[rows, :depth], axis=0),
        "right": np.median(img[rows, ::-1][:depth], axis=0),
    }


def _side_width(profile: np.ndarray, limit: int, tol: float) -> int:
    """Lines (from the edge) of ``profile`` (depth, C) before the first two lines that each
    differ from their inner neighbour by at most ``tol`` of the brightest channel's level past
    ``limit`` (``limit`` when there are none)."""
    scale = float(np.max(np.median(np.abs(profile[limit:]), axis=0)))
    if not scale > 0:
        return 0
    step = np.max(np.abs(np.diff(profile[: limit + 2], axis=0)), axis=1) / scale
    flat = step <= tol
    pairs = np.flatnonzero(flat[:-1] & flat[1:])
    return int(min(pairs[0], limit)) if pairs.size else limit


def edge_widths(
    images: Iterable[np.ndarray], floor: int = 1, tol: float = EDGE_TOL
) -> dict[str, int]:
    """The edge zone of rectified captures, per side.

    Args:
        images: rectified captures (H, W, C) or (H, W) float, linear, of lit patterns (the
            zone is where their lines step toward the surround; a black capture has none).
        floor: the narrowest zone (projector px) returned.
        tol: the step between neighbouring lines (share of the brightest channel) that keeps
            a line in the zone (:data:`EDGE_TOL`).

    Returns:
        ``{"top", "bottom", "left", "right"}`` -> lines (projector px), each the widest over
        ``images``, between ``floor`` and :data:`EDGE_MAX` (the frame's quarter at most).
    """
    widths = dict.fromkeys(SIDES, floor)
    for image in images:
        h, w = image.shape[:2]
        limit = min(EDGE_MAX, h // 4 - LEVEL_LINES, w // 4 - LEVEL_LINES)
        if limit <= floor:
            continue
        for side, prof in _profiles(np.asarray(image), limit + LEVEL_LINES).items():
            widths[side] = max(widths[side], _side_width(prof, limit, tol))
    return widths


def edge_zone(shape: tuple[int, int], widths: Mapping[str, int]) -> np.ndarray:
    """(H, W) bool: the pixels of a projector grid of ``shape`` (H, W) in the edge zone of
    ``widths`` (:func:`edge_widths`): the sides' lines and, at each corner, the square of twice
    the two sides' widths."""
    h, w = shape
    top, bottom, left, right = (int(widths[k]) for k in SIDES)
    zone = np.zeros((h, w), bool)
    zone[:top] = zone[h - bottom :] = True
    zone[:, :left] = zone[:, w - right :] = True
    zone[: 2 * top, : 2 * left] = zone[: 2 * top, w - 2 * right :] = True
    zone[h - 2 * bottom :, : 2 * left] = zone[h - 2 * bottom :, w - 2 * right :] = True
    if zone.all():
        raise ValueError(f"a {w}x{h} grid has no interior inside an edge zone of {dict(widths)}")
    return zone


def fill_edge_zone(images: Iterable[np.ndarray], widths: Mapping[str, int]) -> None:
    """Give every pixel of the edge zone (:func:`edge_zone`) of each of ``images`` (H, W, ...)
    the value of the nearest pixel outside it, in place (all the images share one grid)."""
    from scipy.ndimage import distance_transform_edt

    index: tuple[np.ndarray, np.ndarray] | None = None
    zone = None
    for image in images:
        if zone is None or index is None:
            zone = edge_zone(image.shape[:2], widths)
            near = distance_transform_edt(zone, return_distances=False, return_indices=True)
            index = (near[0][zone], near[1][zone])
        image[zone] = image[index]
