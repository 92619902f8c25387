"""CPU-side frames: yuv420p planes, their conversion to RGB, thumbnails and fitting.

RGB thumbnails are ``viewcomp.calib.comp.compensation.thumbnail``; :func:`thumbnail_planes` makes
the video frames' ones straight from the planes.

No GL here. The yuv420p -> RGB conversion is fixed point and bit-exact with
``shaders/yuv.glsl``: the GL backend converts in the shader, the CPU backend calls
:func:`yuv420p_to_rgb`, and both compensate the very same 8-bit RGB levels.

Conventions: arrays are (rows, columns[, channels]), row 0 at the top; RGB frames are
``uint8`` (H, W, 3) with levels 0..255; yuv420p luma is (H, W), chroma (ceil(H/2), ceil(W/2)).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import cv2
import numpy as np

Colorspace = Literal["bt601", "bt709"]
ColorRange = Literal["limited", "full"]

YUV_SCALE_BITS = 16
_YUV_SHIFT = YUV_SCALE_BITS + 3
_KR_KB = {"bt601": (0.299, 0.114), "bt709": (0.2126, 0.0722)}


@dataclass(frozen=True)
class YuvCoefficients:
    """Integer yuv -> RGB matrix at scale 2^16 (see ``shaders/yuv.glsl``).

    R = cy (Y - y_off) + cr_r Cr', G = cy (Y - y_off) + cb_g Cb' + cr_g Cr',
    B = cy (Y - y_off) + cb_b Cb', with C' = C - 128 (all in 8-bit level units).
    """

    cy: int
    cr_r: int
    cb_b: int
    y_off: int
    cb_g: int
    cr_g: int


def yuv_coefficients(colorspace: Colorspace, color_range: ColorRange) -> YuvCoefficients:
    """The BT.601 / BT.709 matrix for limited (16..235/240) or full (0..255) range."""
    if colorspace not in _KR_KB:
        raise ValueError(f"colorspace must be 'bt601' or 'bt709', got {colorspace!r}")
    if color_range not in ("limited", "full"):
        raise ValueError(f"color_range must be 'limited' or 'full', got {color_range!r}")
    kr, kb = _KR_KB[colorspace]
    kg = 1.0 - kr - kb
    if color_range == "limited":
        sy, sc, y_off = 255.0 / 219.0, 255.0 / 224.0, 16
    else:
        sy, sc, y_off = 1.0, 1.0, 0
    one = float(1 << YUV_SCALE_BITS)
    return YuvCoefficients(
        cy=round(one * sy),
        cr_r=round(one * sc * 2.0 * (1.0 - kr)),
        cb_b=round(one * sc * 2.0 * (1.0 - kb)),
        y_off=y_off,
        cb_g=-round(one * sc * 2.0 * (1.0 - kb) * kb / kg),
        cr_g=-round(one * sc * 2.0 * (1.0 - kr) * kr / kg),
    )


@dataclass
class Planes:
    """One yuv420p video frame as numpy planes (8-bit), with its colour metadata.

    ``y`` (H, W) uint8; ``u``, ``v`` (ceil(H/2), ceil(W/2)) uint8, C-contiguous.
    ``time`` is the presentation time in seconds from the stream's first frame.
    """

    y: np.ndarray
    u: np.ndarray
    v: np.ndarray
    colorspace: Colorspace = "bt709"
    color_range: ColorRange = "limited"
    time: float = 0.0

    @property
    def shape(self) -> tuple[int, int]:
        """(H, W) of the luma plane."""
        return int(self.y.shape[0]), int(self.y.shape[1])

    def check(self) -> None:
        """Raise ValueError unless the plane shapes and dtypes form a yuv420p frame."""
        h, w = self.shape
        want = ((h + 1) // 2, (w + 1) // 2)
        for name, arr in (("y", self.y), ("u", self.u), ("v", self.v)):
            if arr.dtype != np.uint8 or arr.ndim != 2:
                raise ValueError(f"plane {name} must be 2-D uint8, got {arr.dtype} {arr.shape}")
        if self.u.shape != want or self.v.shape != want:
            raise ValueError(
                f"chroma planes must be {want} for luma {(h, w)}, got {self.u.shape}, "
                f"{self.v.shape}"
            )


def _chroma8(c: np.ndarray, h: int, w: int) -> np.ndarray:
    """Bilinear 'left'-sited chroma upsampling, integer weights summing to 8; (h, w) int32."""
    ch, cw = c.shape
    x = np.arange(w)
    y = np.arange(h)
    xc = x >> 1
    yc = y >> 1
    x1 = np.where(x & 1, np.minimum(xc + 1, cw - 1), xc)
    y1 = np.where(y & 1, np.minimum(yc + 1, ch - 1), np.maximum(yc - 1, 0))
    c = c.astype(np.int32)
    near = c[np.ix_(yc, xc)] + c[np.ix_(yc, x1)]
    far = c[np.ix_(y1, xc)] + c[np.ix_(y1, x1)]
    return 3 * near + far


def _levels(y8: np.ndarray, cb: np.ndarray, cr: np.ndarray, k: YuvCoefficients) -> np.ndarray:
    """Fixed-point matrix on luma*8 and chroma*8 (offsets removed) -> (..., 3) uint8."""
    half = 1 << (_YUV_SHIFT - 1)
    top = 255 << _YUV_SHIFT
    luma = k.cy * y8
    out = np.empty((*y8.shape, 3), np.uint8)
    for i, acc in enumerate(
        (luma + k.cr_r * cr, luma + k.cb_g * cb + k.cr_g * cr, luma + k.cb_b * cb)
    ):
        out[..., i] = np.clip(acc + half, 0, top) >> _YUV_SHIFT
    return out


def yuv420p_to_rgb(planes: Planes) -> np.ndarray:
    """RGB levels (H, W, 3) uint8 of a yuv420p frame, bit-exact with ``shaders/yuv.glsl``."""
    planes.check()
    h, w = planes.shape
    k = yuv_coefficients(planes.colorspace, planes.color_range)
    y8 = (planes.y.astype(np.int32) - k.y_off) * 8
    cb = _chroma8(planes.u, h, w) - 1024
    cr = _chroma8(planes.v, h, w) - 1024
    return _levels(y8, cb, cr, k)


def rgb_to_yuv420p(
    rgb: np.ndarray, colorspace: Colorspace = "bt709", color_range: ColorRange = "limited"
) -> Planes:
    """Float reference RGB -> yuv420p (chroma = mean of each 2x2 block); for tests and tools.

    ``rgb`` (H, W, 3) uint8. Not bit-matched to anything; the inverse of
    :func:`yuv420p_to_rgb` up to rounding and chroma subsampling.
    """
    kr, kb = _KR_KB[colorspace]
    kg = 1.0 - kr - kb
    f = rgb.astype(np.float64) / 255.0
    yy = kr * f[..., 0] + kg * f[..., 1] + kb * f[..., 2]
    cb = (f[..., 2] - yy) / (2.0 * (1.0 - kb))
    cr = (f[..., 0] - yy) / (2.0 * (1.0 - kr))
    if color_range == "limited":
        yl, cbl, crl = 16.0 + 219.0 * yy, 128.0 + 224.0 * cb, 128.0 + 224.0 * cr
    else:
        yl, cbl, crl = 255.0 * yy, 128.0 + 255.0 * cb, 128.0 + 255.0 * cr
    h, w = yy.shape

    def sub(c: np.ndarray) -> np.ndarray:
        ph, pw = h + (h & 1), w + (w & 1)
        c = np.pad(c, ((0, ph - h), (0, pw - w)), mode="edge")
        return c.reshape(ph // 2, 2, pw // 2, 2).mean(axis=(1, 3))

    def q(a: np.ndarray) -> np.ndarray:
        return np.ascontiguousarray(np.clip(np.rint(a), 0, 255).astype(np.uint8))

    return Planes(q(yl), q(sub(cbl)), q(sub(crl)), colorspace, color_range)


def thumbnail_planes(planes: Planes, max_side: int = 64) -> np.ndarray:
    """A small RGB thumbnail (h, w, 3) uint8 of a yuv420p frame, longest side <= ~max_side.

    Nearest sampling on an even stride, chroma at the co-sited sample, the same fixed-point
    matrix as :func:`yuv420p_to_rgb`. Both backends call this, so tone statistics agree.
    """
    h, w = planes.shape
    step = max(2, -(-max(h, w) // max_side))
    step += step & 1
    ys = planes.y[::step, ::step]
    us = planes.u[:: step // 2, :: step // 2][: ys.shape[0], : ys.shape[1]]
    vs = planes.v[:: step // 2, :: step // 2][: ys.shape[0], : ys.shape[1]]
    k = yuv_coefficients(planes.colorspace, planes.color_range)
    y8 = (ys.astype(np.int32) - k.y_off) * 8
    cb = (us.astype(np.int32) - 128) * 8
    cr = (vs.astype(np.int32) - 128) * 8
    return _levels(y8, cb, cr, k)


def fit_rect(
    src_w: int, src_h: int, dst_w: int, dst_h: int, even: bool = False
) -> tuple[int, int, int, int]:
    """(x, y, w, h) of a src_w x src_h picture scaled to fit dst, aspect kept, centred.

    With ``even`` all four numbers are even (yuv420p chroma stays aligned), except a size
    equal to the destination's odd size.
    """
    s = min(dst_w / src_w, dst_h / src_h)
    w = min(dst_w, max(1, round(src_w * s)))
    h = min(dst_h, max(1, round(src_h * s)))
    if even:
        w = dst_w if w == dst_w else max(2, w - (w & 1))
        h = dst_h if h == dst_h else max(2, h - (h & 1))
    x = (dst_w - w) // 2
    y = (dst_h - h) // 2
    if even:
        x -= x & 1
        y -= y & 1
    return x, y, w, h


def fit_rgb(rgb: np.ndarray, width: int, height: int) -> np.ndarray:
    """Scale an RGB frame (h, w, 3) uint8 to fit width x height, aspect kept, centred on black.

    Returns the frame itself when it already has the size. INTER_AREA to shrink,
    INTER_LINEAR to enlarge.
    """
    h, w = rgb.shape[:2]
    if (w, h) == (width, height):
        return rgb
    x, y, fw, fh = fit_rect(w, h, width, height)
    interp = cv2.INTER_AREA if fw < w else cv2.INTER_LINEAR
    out = np.zeros((height, width, 3), np.uint8)
    out[y : y + fh, x : x + fw] = cv2.resize(rgb, (fw, fh), interpolation=interp)
    return out


def pad_planes(
    y: np.ndarray,
    u: np.ndarray,
    v: np.ndarray,
    x0: int,
    y0: int,
    width: int,
    height: int,
    color_range: ColorRange,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Place already-scaled planes at even offset (x0, y0) in a black width x height frame."""
    black = 16 if color_range == "limited" else 0
    yy = np.full((height, width), black, np.uint8)
    cu = np.full(((height + 1) // 2, (width + 1) // 2), 128, np.uint8)
    cv = cu.copy()
    yy[y0 : y0 + y.shape[0], x0 : x0 + y.shape[1]] = y
    cu[y0 // 2 : y0 // 2 + u.shape[0], x0 // 2 : x0 // 2 + u.shape[1]] = u
    cv[y0 // 2 : y0 // 2 + v.shape[0], x0 // 2 : x0 // 2 + v.shape[1]] = v
    return yy, cu, cv
