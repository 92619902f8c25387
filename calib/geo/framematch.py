"""Where the projector's frame lies in a camera capture compared with a reference capture: the
one comparison behind the camera-moved checks of `viewcomp capture` (each capture as it
arrives, :mod:`viewcomp.calib.hw.livechecks`) and of `viewcomp calibrate`
(:class:`~viewcomp.calib.geo.checks.MoveCheck`).

What drives the match: the sharp edges of each capture (each gradient component's magnitude
minus its local mean: a ramp's steady slope and smooth shading vanish), i.e. the projector
frame's edges against the unlit surround, the pattern's own edges and the screen's texture.
A straight edge says nothing about a shift along itself, yet its strength along it follows
the pattern times the screen's lobe, which differs from pattern to pattern: matched as one
image of gradient magnitudes, the top and bottom edges of the frame under a left-to-right ramp
on a dark glossy laminate (bluebook, webcam) pulled the peak 20 px sideways, toward where that
product is strongest. So each edge is taken as a contrast - the gradient over the level of its
lit side (the brightest pixel within 2 px) plus :data:`CONTRAST` - which is about the same
along a border wherever it is lit; and the edges across x (the x-gradient) and those across y
are correlated apart and the two surfaces summed, so that the frame's sides, seen only across
x, hold the horizontal shift, while the sum keeps the frame's corners tying the two axes
together (alone, the edges across x of a chessboard matched those of gray 111 px off). Each
axis' shift is then refined on its own edges only. On the emulated webcam's captures of every
measured material (each pattern against its stage's gray; 160x80): at most 0.24 px for a still
camera, at least 1.61 px for a move of 1.80 px.

What is left out: **highlights**. On a glossy screen the projector's lens shows as a small
bright highlight; its ring carried 94 % of the edge energy of a gray capture in 0.26 % of the
pixels (measured on a red specular plastic), its shape changes with what each pattern shows
there, and it moves about half as far as the frame when the camera moves (the mirror point
lies between projector and camera). Matched as it is, it made still cameras look moved by up
to 6 px and moved ones look still. So in each image the pixels brighter than
:data:`HIGHLIGHT` times the lit level (the 90th percentile of the capture over the lit
region), or clipped (codes at the top), grown by :data:`HIGHLIGHT_GROW_PX` and feathered
(:data:`FEATHER_PX`), get weight 0; the brightness is capped at that level before the
gradient; both edge images are multiplied by the product of the two weights, so each
highlight is left out of both.

The shift: the normalised cross-correlation of the two weighted edge images (by FFT, over the
lit region's bounding box and a margin), its integer peak refined by a parabola through the
peak and its neighbours, then re-centred by the Fourier shift theorem and refined again.
Phase correlation (OpenCV's ``phaseCorrelate``), used before, measured 1.1-1.3 px for frames
that had moved 1.49 px; this measures 1.40-1.50 and 0.00-0.05 for a still camera (simulated
at 320x160, every measured material, also with 3 codes of noise, JPEG at quality 70 and a 3 %
exposure drift added). The correlation coefficient at the peak, ``match`` in 0..1 (the mean
of the two axes'), says how clearly the two show the same frame (measured: 0.33-1.0 for two
captures of one rig, the emulated webcam on every measured material included).

Units: camera pixels, x right, y down; images (Hc, Wc, 3) linear float, any exposure scale
(each is normalised by its own lit level, so an exposure drift of a few percent changes
nothing).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from viewcomp.calib.geo.captures import channel_mean

MOVE_LIMIT_PX = 1.0  # camera pixels: a larger shift between two captures means the camera moved
MIN_MATCH = 0.15  # correlation below which two captures do not show the same frame
HIGHLIGHT = 2.0  # brighter than this times the lit level: a highlight, left out
HIGHLIGHT_GROW_PX = 4  # a highlight's mask grows by this (its ring lies around it)
FEATHER_PX = 3.0  # Gaussian sigma of the mask's soft edge (a hard edge would match itself)
CONTRAST = 0.1  # of the lit level: an edge's gradient over its lit side's level plus this
LOCAL_MEAN_PX = 4.0  # Gaussian sigma of the local mean taken off the gradient magnitude
LIT_PERCENTILE = 97.0  # the lit region: above LIT_FRACTION of this percentile of white - black
LIT_FRACTION = 0.1  # measured: a broad lobe's dim sides 0.18 of it, the unlit surround < 0.03
MARGIN = 0.05  # of the image's larger side (at least 16 px) kept around the lit region


def lit_region(white: np.ndarray, black: np.ndarray | None = None) -> np.ndarray:
    """(Hc, Wc) bool: where the projector lights the screen in ``white`` (Hc, Wc, 3) linear
    (``black`` (Hc, Wc, 3), when given, subtracted): above :data:`LIT_FRACTION` of the
    :data:`LIT_PERCENTILE` th percentile, which a small highlight does not reach and the
    dim edge of a broad lobe does."""
    g = channel_mean(white)
    if black is not None:
        g = g - channel_mean(black)
    top = float(np.percentile(g, LIT_PERCENTILE))
    return g > LIT_FRACTION * top


@dataclass(frozen=True)
class FrameEdges:
    """The edges of one capture within ``box`` (y0, y1, x0, x1) of the camera image:
    ``edges`` (2, h, w) float32 >= 0, the edges across x then across y, and ``weight``
    (h, w) float32 in 0..1, 0 on highlights and clipped pixels."""

    edges: np.ndarray
    weight: np.ndarray
    box: tuple[int, int, int, int]


@dataclass(frozen=True)
class Shift:
    """How far an image's frame lies from the reference's: ``dx``, ``dy`` camera px (the
    image's minus the reference's) and ``match`` in 0..1 (below :data:`MIN_MATCH` the shift
    means nothing)."""

    dx: float
    dy: float
    match: float

    @property
    def distance(self) -> float:
        """The shift's length in camera px."""
        return float(np.hypot(self.dx, self.dy))


def frame_edges(img: np.ndarray, lit: np.ndarray, clipped: np.ndarray | None = None) -> FrameEdges:
    """The edges of ``img`` (Hc, Wc, 3) linear to compare (see the module doc).

    ``lit``: (Hc, Wc) bool of :func:`lit_region` (the same for every image compared: it sets
    the box and where the lit level is measured); ``clipped``: (Hc, Wc) or (Hc, Wc, 3) bool,
    pixels at the top code (None: none known).
    """
    box = _box(lit)
    y0, y1, x0, x1 = box
    g = channel_mean(img)[y0:y1, x0:x1]
    inside = lit[y0:y1, x0:x1]
    level = float(np.percentile(g[inside], 90)) if inside.any() else 0.0
    g = g / max(level, 1e-9)
    bright = g > HIGHLIGHT
    if clipped is not None:
        c = np.asarray(clipped, bool)
        bright |= (np.any(c, axis=2) if c.ndim == 3 else c)[y0:y1, x0:x1]
    size = 2 * HIGHLIGHT_GROW_PX + 1
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (size, size))
    grown = cv2.dilate(bright.astype(np.uint8), kernel).astype(np.float32)
    weight = 1.0 - np.minimum(1.0, 2.0 * cv2.GaussianBlur(grown, (0, 0), FEATHER_PX))
    g = np.minimum(g, np.float32(HIGHLIGHT))
    bright_near = cv2.dilate(g, np.ones((5, 5), np.uint8))  # the lit side of each edge
    edges = np.empty((2, *g.shape), np.float32)
    for axis, (ox, oy) in enumerate(((1, 0), (0, 1))):
        e = np.abs(cv2.Sobel(g, cv2.CV_32F, ox, oy, ksize=3))
        e = e / (bright_near + CONTRAST)
        edges[axis] = np.maximum(e - cv2.GaussianBlur(e, (0, 0), LOCAL_MEAN_PX), 0.0)
    return FrameEdges(edges, weight.astype(np.float32), box)


def frame_shift(reference: FrameEdges, image: FrameEdges) -> Shift:
    """How far ``image``'s frame lies from ``reference``'s (both of :func:`frame_edges` with
    the same ``lit``): the peak of the sum of the two axes' normalised cross-correlations,
    then dx refined on the edges across x and dy on those across y (parabola, then the
    Fourier shift theorem), to about 0.05 px; ``match`` the mean of the two at the peak."""
    if reference.box != image.box:
        raise ValueError(f"edge images of different boxes: {reference.box} and {image.box}")
    w = reference.weight * image.weight
    cx = _Correlation(reference.edges[0] * w, image.edges[0] * w)
    cy = _Correlation(reference.edges[1] * w, image.edges[1] * w)
    both = cx.surface + cy.surface
    h, wd = both.shape
    iy, ix = np.unravel_index(int(np.argmax(both)), both.shape)
    dx = (ix if ix <= wd // 2 else ix - wd) + _vertex(
        cx.surface[iy, (ix - 1) % wd], cx.surface[iy, ix], cx.surface[iy, (ix + 1) % wd]
    )
    dy = (iy if iy <= h // 2 else iy - h) + _vertex(
        cy.surface[(iy - 1) % h, ix], cy.surface[iy, ix], cy.surface[(iy + 1) % h, ix]
    )
    match = 0.0
    for _ in range(2):  # re-centre on the estimate: the parabola is exact near its vertex
        sx = cx.around(dx, dy)
        sy = cy.around(dx, dy)
        dx += _vertex(sx[0, -1], sx[0, 0], sx[0, 1])
        dy += _vertex(sy[-1, 0], sy[0, 0], sy[1, 0])
        match = 0.5 * (float(sx[0, 0]) + float(sy[0, 0]))  # the last step moves < 0.05 px
    return Shift(float(dx), float(dy), float(np.clip(match, 0.0, 1.0)))


class _Correlation:
    """The normalised circular cross-correlation of ``b`` against ``a`` (both (h, w), their
    means taken off): ``surface`` (h, w), at integer shifts (index = shift modulo the size),
    0 everywhere when either is flat."""

    def __init__(self, a: np.ndarray, b: np.ndarray) -> None:
        a = a - a.mean()
        b = b - b.mean()
        norm = float(np.sqrt(np.sum(a * a) * np.sum(b * b)))
        self.shape = a.shape
        self.cross = np.fft.rfft2(b) * np.conj(np.fft.rfft2(a)) / max(norm, 1e-30)
        if norm <= 0:
            self.cross[:] = 0
        self.surface = np.fft.irfft2(self.cross, s=self.shape)

    def around(self, dx: float, dy: float) -> np.ndarray:
        """The surface re-centred on the sub-pixel shift (dx, dy): its [0, 0] is the
        correlation there, [0, +-1] and [+-1, 0] one pixel either side."""
        ky = np.fft.fftfreq(self.shape[0])[:, None]
        kx = np.fft.rfftfreq(self.shape[1])[None, :]
        ramp = np.exp(2j * np.pi * ky * dy) * np.exp(2j * np.pi * kx * dx)  # (h, 1) x (1, w)
        return np.fft.irfft2(self.cross * ramp, s=self.shape)


def _vertex(before: float, peak: float, after: float) -> float:
    """The vertex (-0.5..0.5) of the parabola through three samples at -1, 0, 1."""
    den = before - 2.0 * peak + after
    if den >= 0:
        return 0.0
    return float(np.clip(0.5 * (before - after) / den, -0.5, 0.5))


def _box(lit: np.ndarray) -> tuple[int, int, int, int]:
    """The lit region's bounding box with :data:`MARGIN`, clipped to the image: the rows and
    columns at least 1 % lit (a stray noisy pixel does not widen it)."""
    hc, wc = lit.shape
    m = max(16, round(MARGIN * max(hc, wc)))
    rows = np.nonzero(np.count_nonzero(lit, axis=1) >= max(2, wc // 100))[0]
    cols = np.nonzero(np.count_nonzero(lit, axis=0) >= max(2, hc // 100))[0]
    if len(rows) == 0 or len(cols) == 0:
        return 0, hc, 0, wc
    return (
        max(0, int(rows[0]) - m),
        min(hc, int(rows[-1]) + 1 + m),
        max(0, int(cols[0]) - m),
        min(wc, int(cols[-1]) + 1 + m),
    )
