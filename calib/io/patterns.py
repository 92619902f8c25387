"""Calibration patterns to project: Table 1 of the paper, a chessboard, Gray code and
phase-shifted sinusoids.

All patterns are 8-bit encoded RGB images (h, w, 3) uint8, 0..255, at the projector's
resolution: exactly the values the projector is sent. Pixel (u, v) is array ``[v, u]``;
pixel centres sit at integer coordinates.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from viewcomp.calib.io.atomic import atomic_dir
from viewcomp.calib.io.imageio import write_png

# The gray pattern U's level in every channel (Table 1); Eq. 25's feedback divides by it.
GRAY_LEVEL = 110.0

# The colour patterns' own channel in Table 1 (the others at the gray level).
TABLE1_COLOUR_LEVEL = 130


def table1_colours(level: int = TABLE1_COLOUR_LEVEL) -> dict[str, tuple[int, int, int]]:
    """Red, green and blue at ``level`` (111..255) in their own channel and the gray level in
    the others, and gray: the RGB triple of each uniform pattern of Table 1."""
    if not int(GRAY_LEVEL) < int(level) <= 255:
        raise ValueError(f"colour_level must be in 111..255, got {level!r}")
    c, g = int(level), int(GRAY_LEVEL)
    return {"red": (c, g, g), "green": (g, c, g), "blue": (g, g, c), "gray": (g, g, g)}


def _check_size(w: int, h: int, min_w: int = 1, min_h: int = 1) -> None:
    if not (isinstance(w, int | np.integer) and isinstance(h, int | np.integer)):
        raise ValueError(f"pattern size must be integers, got {w!r}x{h!r}")
    if w < min_w or h < min_h:
        raise ValueError(f"pattern size must be integers of at least {min_w}x{min_h}, got {w}x{h}")


def ramp_levels(w: int) -> np.ndarray:
    """The ramp's level per column, (w,) uint8: I(u) = round(255 u / (w - 1)), u = 0..w-1.

    Rounds halves up, in exact integer arithmetic (floor((510 u + (w - 1)) / (2 (w - 1))));
    for w = 640 no column is a tie, so this equals numpy's round-half-to-even.
    """
    _check_size(w, 1, min_w=2)
    u = np.arange(w, dtype=np.int64)
    return ((510 * u + (w - 1)) // (2 * (w - 1))).astype(np.uint8)  # 0..255


#: The colour patterns' own channel in a camera capture (`viewcomp capture` on a device): the
#: fits read only ratios of a colour pattern's rise over gray, so the level is free, and a rise
#: of 20 levels (Table 1's 130) leaves the cross-talk it measures a difference of 2-3 codes in an
#: 8-bit frame, the size of an MJPEG codec's chroma quantisation (docs/EVALUATION.md).
CAMERA_COLOUR_LEVEL = 255


def table1_patterns(
    w: int, h: int, colour_level: int = TABLE1_COLOUR_LEVEL
) -> dict[str, np.ndarray]:
    """Table 1 patterns, each (h, w, 3) uint8 encoded: red (130,110,110), green (110,130,110),
    blue (110,110,130), gray U (110,110,110), ramp S (every row :func:`ramp_levels` in all
    three channels) and black (0,0,0). ``colour_level``: the colour patterns' own channel
    (111..255; :func:`table1_colours`)."""
    _check_size(w, h, min_w=2)
    out = {
        name: np.broadcast_to(np.array(rgb, np.uint8), (h, w, 3)).copy()
        for name, rgb in table1_colours(colour_level).items()
    }
    levels = ramp_levels(w)
    out["ramp"] = np.broadcast_to(levels[None, :, None], (h, w, 3)).copy()
    out["black"] = np.zeros((h, w, 3), np.uint8)
    return out


#: The per-primary patterns a mono camera's set adds (docs/MODEL.md, "Mono cameras"): each
#: projector primary alone at the gray level (``red_alone`` = (110, 0, 0), ...) and alone on
#: the ramp (``ramp_red`` = every row :func:`ramp_levels` in red only, ...).
PRIMARY_PATTERNS = ("red_alone", "green_alone", "blue_alone", "ramp_red", "ramp_green", "ramp_blue")


def primary_patterns(w: int, h: int) -> dict[str, np.ndarray]:
    """The :data:`PRIMARY_PATTERNS`, each (h, w, 3) uint8: primary j alone at
    :data:`GRAY_LEVEL` (the others 0), and primary j alone on the ramp."""
    _check_size(w, h, min_w=2)
    out: dict[str, np.ndarray] = {}
    levels = ramp_levels(w)
    for j, colour in enumerate(("red", "green", "blue")):
        alone = np.zeros((h, w, 3), np.uint8)
        alone[..., j] = int(GRAY_LEVEL)
        out[f"{colour}_alone"] = alone
        ramp = np.zeros((h, w, 3), np.uint8)
        ramp[..., j] = levels[None, :]
        out[f"ramp_{colour}"] = ramp
    return {name: out[name] for name in PRIMARY_PATTERNS}


def chessboard(w: int, h: int, squares: tuple[int, int] = (9, 6)) -> tuple[np.ndarray, np.ndarray]:
    """A black-and-white chessboard centred on a white margin, for cv2.findChessboardCorners.

    ``squares`` is the number of squares (columns, rows); the board has
    (columns - 1) x (rows - 1) inner corners, which is the ``patternSize`` to give OpenCV.
    The square side is floor(min(w / (columns + 2), h / (rows + 2))) pixels, so the white
    margin is at least one square wide. The top-left square is black.

    Returns the image (h, w, 3) uint8 (0 and 255) and the inner corners (N, 2) float64 in
    projector pixels (u, v), row by row from the top-left, N = (columns - 1) (rows - 1). A
    corner lies between pixels, e.g. at u = x0 + i s - 0.5.
    """
    cols, rows = squares
    if cols < 3 or rows < 3:
        raise ValueError(f"a chessboard needs at least 3x3 squares, got {cols}x{rows}")
    _check_size(w, h)
    side = min(w // (cols + 2), h // (rows + 2))
    if side < 4:
        raise ValueError(
            f"{w}x{h} is too small for a {cols}x{rows} chessboard (squares would be {side} px)"
        )
    x0 = (w - cols * side) // 2
    y0 = (h - rows * side) // 2
    img = np.full((h, w), 255, np.uint8)
    for j in range(rows):
        for i in range(cols):
            if (i + j) % 2 == 0:
                img[y0 + j * side : y0 + (j + 1) * side, x0 + i * side : x0 + (i + 1) * side] = 0
    ii, jj = np.meshgrid(np.arange(1, cols), np.arange(1, rows))
    corners = np.stack([x0 + ii.ravel() * side - 0.5, y0 + jj.ravel() * side - 0.5], axis=1).astype(
        np.float64
    )
    return np.repeat(img[:, :, None], 3, axis=2), corners


def graycode_patterns(w: int, h: int) -> tuple[list[np.ndarray], np.ndarray, np.ndarray]:
    """OpenCV's Gray-code structured-light patterns for a w x h projector.

    Returns (patterns, white, black): the list from
    ``cv2.structured_light.GrayCodePattern_create(w, h).generate()`` in OpenCV's order (each
    bit plane followed by its inverse, columns then rows), and the all-white / all-black pair
    used for the shadow masks when decoding. All (h, w, 3) uint8, 0 or 255.
    """
    _check_size(w, h)
    gen = cv2.structured_light.GrayCodePattern_create(w, h)
    ok, planes = gen.generate()
    if not ok:
        raise RuntimeError(f"OpenCV could not generate Gray-code patterns for {w}x{h}")
    black, white = gen.getImagesForShadowMasks(None, None)  # OpenCV order: (black, white)

    def rgb(p: np.ndarray) -> np.ndarray:
        return np.repeat(np.asarray(p, np.uint8).reshape(h, w)[:, :, None], 3, axis=2)

    return [rgb(p) for p in planes], rgb(white), rgb(black)


# Phase shifting: sinusoids of PHASE_PERIOD projector pixels, each shown at PHASE_SHIFTS phases.
# 32 px is about 19 camera px for a camera with 0.6 camera px per projector px (resolved even
# after blur and pixel integration), and 4x the 8-px Gray-code stripes that such a camera still
# resolves, which the unwrapping needs. 8 shifts cancel the projector response's harmonics 2-6
# in the phase (only harmonics 7 and 9 alias onto the fundamental; see
# :mod:`viewcomp.calib.geo.phaseshift`).
PHASE_PERIOD = 32
PHASE_SHIFTS = 8
# The sinusoids' lowest level: the projector's frame stays brightly lit all round in every
# shift. A sinusoid from 0 leaves the frame's left and right edges dark in some shifts, and the
# live camera-moved check, which matches the frame's edges with the gray capture's, then reads
# shifts near its 1-camera-px limit (0.85 px at 0.6 camera px per projector px with a floor of
# 128, 0.41 px with 192). The cost: about half the modulation (the phase stays far more
# precise than needed).
PHASE_FLOOR = 192
PHASE_AXES = ("col", "row")


def phase_names(shifts: int = PHASE_SHIFTS) -> list[str]:
    """Capture names of the phase-shift patterns: ``phase_col_0`` ... ``phase_col_{N-1}``
    (varying along projector columns u), then ``phase_row_0`` ... (along rows v)."""
    return [f"phase_{axis}_{n}" for axis in PHASE_AXES for n in range(shifts)]


def phase_patterns(
    w: int, h: int, period: int = PHASE_PERIOD, shifts: int = PHASE_SHIFTS
) -> dict[str, np.ndarray]:
    """Phase-shifted sinusoids, by capture name (:func:`phase_names`), each (h, w, 3) uint8.

    ``phase_col_n`` at projector pixel (u, v) is round(F + (255 - F) (1 + cos(2 pi u / period -
    2 pi n / shifts)) / 2) in every channel (halves rounded up; F = :data:`PHASE_FLOOR`),
    constant along v; ``phase_row_n`` the same in v. So the phase 2 pi u / period is 0 at
    u = 0 (pixel centres at integers), and shift n delays it by 2 pi n / shifts.
    """
    _check_size(w, h)
    if not (isinstance(period, int) and period >= 4):
        raise ValueError(f"phase period must be an integer of at least 4 pixels, got {period!r}")
    if not (isinstance(shifts, int) and shifts >= 3):
        raise ValueError(f"phase shifts must be an integer of at least 3, got {shifts!r}")
    out: dict[str, np.ndarray] = {}
    for axis, size in zip(PHASE_AXES, (w, h), strict=True):
        x = np.arange(size, dtype=np.float64)
        for n in range(shifts):
            wave = 0.5 + 0.5 * np.cos(2.0 * np.pi * (x / period - n / shifts))
            line = np.floor(PHASE_FLOOR + (255.0 - PHASE_FLOOR) * wave + 0.5).astype(np.uint8)
            img = line[None, :] if axis == "col" else line[:, None]
            out[f"phase_{axis}_{n}"] = np.broadcast_to(img[..., None], (h, w, 3)).copy()
    return out


def write_patterns(out_dir: str | Path, w: int, h: int) -> list[Path]:
    """Write every pattern to project as 8-bit RGB PNGs: the folder ``out_dir`` is written
    whole and replaces any old one (:func:`~viewcomp.calib.io.atomic.atomic_dir`).

    Files: red.png green.png blue.png gray.png ramp.png black.png (Table 1), chessboard.png
    (:func:`chessboard` with the default squares), graycode_00.png ... (:func:`graycode_patterns`,
    two digits or more), graycode_white.png graycode_black.png and phase_col_0.png ...
    phase_row_7.png (:func:`phase_patterns`). Returns the paths in that order.
    """
    out = Path(out_dir)
    images: dict[str, np.ndarray] = dict(table1_patterns(w, h))
    images["chessboard"] = chessboard(w, h)[0]
    planes, white, black = graycode_patterns(w, h)
    digits = max(2, len(str(len(planes) - 1)))
    for k, p in enumerate(planes):
        images[f"graycode_{k:0{digits}d}"] = p
    images["graycode_white"] = white
    images["graycode_black"] = black
    images.update(phase_patterns(w, h))
    with atomic_dir(out) as staging:
        for name, img in images.items():
            write_png(staging / f"{name}.png", img)
    return [out / f"{name}.png" for name in images]
