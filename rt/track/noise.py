"""How noisy a face's picture is, and how much to smooth its refinement crop.

A webcam in a dim room raises its gain: the picture keeps its brightness and gains noise.
YuNet reads the eyes of a noisy face too far apart, so the face is ranged short, the more
the noisier (simulated faces 0.8-3.5 m from a 720p webcam, the far ones most; noise as a
share of full scale on faces of full contrast: 2 %, median distance 0.97-1.00 of the truth;
4 %, 0.94-0.99; 6 %, 0.93-0.97; a face lit at 0.3 with 2 % noise, 0.95-0.98). What counts
is the noise against the face's own contrast: :func:`relative_noise`.

Smoothing the refinement crop takes the bias back, but a smoothed face also moves YuNet's
nose less when the head turns (the yaw is read short), so a crop is smoothed only as much
as its noise calls for (:func:`smoothing`): a Gaussian whose spatial averaging brings the
noise down to ``QUIET`` of the face's contrast, where YuNet's eyes are measured unbiased
(the 2 % above); a face quieter than that is not smoothed at all.

The noise is estimated from the frame's own pixels around the face (Immerkaer's operator, the
second differences that cancel smooth shading, and the median of their magnitudes: robust to
the edges of a face and a room), once per refinement crop, and the smoothing is done there,
at the frame's resolution where the noise is (:func:`smoothed_around`), before the crop is
drawn enlarged: a few times fewer pixels than the crop's.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from viewcomp.rt.track.boxes import around

# The noise, as a share of the face's contrast (``relative_noise``'s units: the grey
# level's noise, about 2/3 of each colour channel's), up to which YuNet's eyes are read
# unbiased: simulated faces of full contrast with 2 % of full scale of noise in each channel
# (poses drawn for this, not the tracker's test) read 0.965-1.002 of the distance, 1 % alike.
QUIET = 0.021
# Frame pixels: the most a crop is smoothed (a far face's eyes are 10-15 pixels apart).
MAX_SIGMA = 1.5
SAMPLES = 20000  # second differences enough for the median (its error about 1 %)
# Immerkaer's mask: second differences in both directions, zero on any plane; white noise
# of standard deviation s gives a response of standard deviation 6 s.
_MASK = np.array([[1, -2, 1], [-2, 4, -2], [1, -2, 1]], np.float32)


def noise_sigma(grey: np.ndarray) -> float:
    """The standard deviation of the pixel noise in ``grey`` ((h, w), any real type,
    h, w >= 3), in its units: the median magnitude of Immerkaer's second differences,
    taken as a normal distribution's (1.4826 MAD), over 6; the median of every other
    difference in each direction where there are more than ``SAMPLES``."""
    r = cv2.filter2D(np.asarray(grey, np.float32), -1, _MASK)[1:-1, 1:-1]
    step = max(1, int(math.sqrt(r.size / SAMPLES)))
    return float(1.4826 * np.median(np.abs(r[::step, ::step])) / 6.0)


def relative_noise(frame: np.ndarray, box: np.ndarray) -> float:
    """The pixel noise around the face at ``box`` (x, y, w, h pixels) of ``frame`` ((h, w,
    3) uint8 BGR, or (h, w) grey): its standard deviation in the square two box sizes each
    side of the box's centre, over the face's contrast (the 95th minus the 5th percentile of
    the grey levels inside the box); 0 where the box holds no contrast or too few pixels."""
    rx0, ry0, rx1, ry1 = around(box, 2.0, frame.shape)
    fh, fw = frame.shape[:2]
    bx0, by0 = int(max(0.0, box[0])), int(max(0.0, box[1]))
    bx1, by1 = int(min(fw, box[0] + box[2])), int(min(fh, box[1] + box[3]))
    if rx1 - rx0 < 3 or ry1 - ry0 < 3 or bx1 <= bx0 or by1 <= by0:
        return 0.0
    region = frame[ry0:ry1, rx0:rx1]
    grey = cv2.cvtColor(region, cv2.COLOR_BGR2GRAY) if region.ndim == 3 else region
    inside = grey[by0 - ry0 : by1 - ry0, bx0 - rx0 : bx1 - rx0]
    lo, hi = np.percentile(inside, (5.0, 95.0))
    if hi - lo <= 0:
        return 0.0
    return noise_sigma(grey) / float(hi - lo)


def smoothed_around(frame: np.ndarray, box: np.ndarray, sigma: float, sides: float) -> np.ndarray:
    """A copy of ``frame`` ((h, w, ...) uint8) with the square ``sides`` box sizes each side
    of ``box``'s centre (x, y, w, h pixels) smoothed by a Gaussian of ``sigma`` pixels (its
    edge reads the pixels beyond, as the whole frame smoothed would): what a refinement crop
    of that square is drawn from. The rest of the frame is left as it is."""
    out = frame.copy()
    x0, y0, x1, y1 = around(box, sides, frame.shape)
    pad = math.ceil(3.0 * sigma) + 1
    fh, fw = frame.shape[:2]
    px0, py0, px1, py1 = max(0, x0 - pad), max(0, y0 - pad), min(fw, x1 + pad), min(fh, y1 + pad)
    if px1 <= px0 or py1 <= py0:
        return out
    blurred = cv2.GaussianBlur(frame[py0:py1, px0:px1], (0, 0), sigma)
    out[y0:y1, x0:x1] = blurred[y0 - py0 : y1 - py0, x0 - px0 : x1 - px0]
    return out


def smoothing(rho: float, quiet: float = QUIET) -> float:
    """Frame pixels: the standard deviation of the Gaussian that brings relative noise
    ``rho`` down to ``quiet`` (0 where ``rho`` <= ``quiet``; at most :data:`MAX_SIGMA`). A
    Gaussian of standard deviation s pixels averages white noise down by about
    1 / (2 sqrt(pi) s)."""
    if not rho > quiet:
        return 0.0
    return min(MAX_SIGMA, rho / (2.0 * math.sqrt(math.pi) * quiet))
