"""Test images for the evaluation: natural photographs and uniform colours.

The photographs are scikit-image's sample images that its wheel ships inside the package
(``skimage/data/astronaut.png``, ``coffee.png``, ``chelsea.png``; public domain / CC0). They
are read straight from the installed package folder with OpenCV, never through
``skimage.data``'s fetcher, so nothing is ever downloaded. If a future scikit-image stops
shipping them, deterministic procedural stand-ins are used instead (:func:`procedural_images`).

All images are 8-bit encoded RGB (h, w, 3) uint8, 0..255 (sRGB-like, as a video frame).
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import cv2
import numpy as np

from viewcomp.calib.io.imageio import CaptureError, read_rgb8

PHOTOS = ("astronaut", "coffee", "chelsea")
# Vertical crop position (0 top, 0.5 centre, 1 bottom): the astronaut's face is near the top.
_ANCHOR_Y = {"astronaut": 0.2, "coffee": 0.5, "chelsea": 0.5}


def _skimage_data_dir() -> Path | None:
    """scikit-image's package data folder, found without importing scikit-image."""
    spec = importlib.util.find_spec("skimage")
    if spec is None or not spec.submodule_search_locations:
        return None
    return Path(next(iter(spec.submodule_search_locations))) / "data"


def fit_crop(img: np.ndarray, w: int, h: int, anchor_y: float = 0.5) -> np.ndarray:
    """Scale (h0, w0, 3) uint8 ``img`` to cover w x h (aspect kept, cv2.INTER_AREA) and crop
    to (h, w, 3) uint8: centred horizontally, at ``anchor_y`` (0 top, 0.5 centre, 1 bottom)
    vertically."""
    h0, w0 = img.shape[:2]
    scale = max(w / w0, h / h0)
    nw, nh = max(w, round(w0 * scale)), max(h, round(h0 * scale))
    resized = cv2.resize(img, (nw, nh), interpolation=cv2.INTER_AREA)
    x0, y0 = (nw - w) // 2, round((nh - h) * min(max(anchor_y, 0.0), 1.0))
    return np.ascontiguousarray(resized[y0 : y0 + h, x0 : x0 + w])


def _read_photo(path: Path) -> np.ndarray | None:
    try:
        return read_rgb8(path)
    except CaptureError:  # missing or unreadable: the procedural images stand in
        return None


def natural_images(w: int, h: int) -> dict[str, np.ndarray]:
    """Three natural images, each (h, w, 3) uint8 encoded RGB, scaled to cover w x h and
    cropped (centred; the astronaut's crop sits higher to keep the face).

    Photographs ("astronaut", "coffee", "chelsea") when scikit-image ships them, else the
    procedural "landscape", "still_life", "portrait". Never downloads anything.
    """
    _check(w, h)
    folder = _skimage_data_dir()
    if folder is not None:
        photos = {name: _read_photo(folder / f"{name}.png") for name in PHOTOS}
        if all(p is not None for p in photos.values()):
            return {
                name: fit_crop(p, w, h, _ANCHOR_Y[name])
                for name, p in photos.items()
                if p is not None
            }
    return procedural_images(w, h)


def uniform(rgb: tuple[int, int, int], w: int, h: int) -> np.ndarray:
    """A uniform image (h, w, 3) uint8 of encoded colour ``rgb`` (three ints 0..255)."""
    _check(w, h)
    if len(rgb) != 3 or not all(isinstance(c, int | np.integer) and 0 <= c <= 255 for c in rgb):
        raise ValueError(f"rgb must be three integers 0..255, got {rgb!r}")
    return np.broadcast_to(np.array(rgb, np.uint8), (h, w, 3)).copy()


def _check(w: int, h: int) -> None:
    if w < 1 or h < 1:
        raise ValueError(f"image size must be positive, got {w}x{h}")


# ---------------------------------------------------------------------------------------------
# Procedural stand-ins (deterministic)


def _smooth_noise(rng: np.random.Generator, h: int, w: int, cells: int) -> np.ndarray:
    """Band-limited noise (h, w) float32 in about -1..1: a coarse random grid, upsampled."""
    gh, gw = max(2, cells * h // max(h, w) + 2), max(2, cells * w // max(h, w) + 2)
    grid = rng.standard_normal((gh, gw)).astype(np.float32)
    return cv2.resize(grid, (w, h), interpolation=cv2.INTER_CUBIC)


def _to_u8(img: np.ndarray) -> np.ndarray:
    return np.clip(np.round(img * 255.0), 0, 255).astype(np.uint8)


def _landscape(w: int, h: int, rng: np.random.Generator) -> np.ndarray:
    y = np.linspace(0.0, 1.0, h, dtype=np.float32)[:, None]
    x = np.linspace(0.0, 1.0, w, dtype=np.float32)[None, :]
    sky_top, sky_low = np.array([0.25, 0.45, 0.85]), np.array([0.85, 0.88, 0.95])
    t = np.clip(y / 0.55, 0, 1)[..., None]
    img = sky_top * (1 - t) + sky_low * t + 0.04 * _smooth_noise(rng, h, w, 6)[..., None]
    img = np.broadcast_to(img, (h, w, 3)).copy()
    # sun glow
    d = np.sqrt((x - 0.75) ** 2 + ((y - 0.2) * h / w) ** 2)
    img += (np.exp(-((d / 0.06) ** 2)) * 0.6)[..., None] * np.array([1.0, 0.9, 0.6])
    # two ranges of hills
    for base, amp, colour, cells in (
        (0.45, 0.08, (0.30, 0.42, 0.30), 5),
        (0.58, 0.06, (0.18, 0.35, 0.12), 9),
    ):
        ridge = base + amp * _smooth_noise(rng, 1, w, cells)[0][None, :]
        mask = (y > ridge)[..., None]
        shade = 0.85 + 0.15 * _smooth_noise(rng, h, w, 40)[..., None]
        img = np.where(mask, np.array(colour) * shade, img)
    # water with ripples below 0.72
    water = y > 0.72
    ripple = 0.5 + 0.5 * np.sin(60 * y + 3 * _smooth_noise(rng, h, w, 30))
    wcol = np.array([0.15, 0.30, 0.45]) + 0.12 * ripple[..., None] * np.array([0.6, 0.8, 1.0])
    img = np.where(water[..., None], wcol, img)
    return _to_u8(img)


def _still_life(w: int, h: int, rng: np.random.Generator) -> np.ndarray:
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    s = float(min(w, h))
    img = np.empty((h, w, 3), np.float32)
    img[:] = np.array([0.55, 0.42, 0.30])  # wooden table
    img *= (0.85 + 0.15 * np.sin(x / s * 40 + 2 * _smooth_noise(rng, h, w, 8)))[..., None]
    wall = y < 0.45 * h
    img[wall] = np.array([0.78, 0.74, 0.66])
    light = np.array([-0.5, -0.6, 0.62])
    light /= np.linalg.norm(light)
    fruits = [
        (0.28, 0.62, 0.17, (0.85, 0.12, 0.10)),  # red apple
        (0.52, 0.60, 0.15, (0.95, 0.60, 0.08)),  # orange
        (0.73, 0.64, 0.13, (0.35, 0.65, 0.15)),  # green pear
        (0.62, 0.42, 0.11, (0.45, 0.15, 0.45)),  # plum
    ]
    for cx, cy, r, colour in fruits:
        dx, dy = (x - cx * w) / (r * s), (y - cy * h) / (r * s)
        rr = dx * dx + dy * dy
        inside = rr < 1.0
        nz = np.sqrt(np.clip(1.0 - rr, 0.0, 1.0))
        lambert = np.clip(dx * light[0] + dy * light[1] + nz * light[2], 0.0, 1.0)
        spec = lambert**40
        col = np.array(colour) * (0.15 + 0.85 * lambert)[..., None] + 0.6 * spec[..., None]
        # soft contact shadow
        shadow = np.exp(
            -(
                ((x - cx * w) / (1.2 * r * s)) ** 2
                + ((y - (cy + 0.9 * r) * h) / (0.25 * r * s)) ** 2
            )
        )
        img *= (1.0 - 0.5 * shadow * ~inside)[..., None]
        img[inside] = col[inside]
    return _to_u8(img)


def _portrait(w: int, h: int, rng: np.random.Generator) -> np.ndarray:
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    u, v = x / w, y / h
    bg = np.array([0.20, 0.32, 0.38]) * (0.7 + 0.3 * (1 - v))[..., None]
    img = bg + 0.03 * _smooth_noise(rng, h, w, 5)[..., None]
    s = float(min(w, h))
    # face: an ellipse with soft skin-tone shading
    fx, fy = (x - 0.5 * w) / (0.22 * s), (y - 0.45 * h) / (0.32 * s)
    rr = fx * fx + fy * fy
    face = rr < 1.0
    shade = np.clip(1.0 - 0.45 * rr - 0.25 * fx, 0.0, 1.0)
    skin = np.array([0.92, 0.70, 0.58]) * (0.35 + 0.65 * shade)[..., None]
    skin += 0.015 * _smooth_noise(rng, h, w, 80)[..., None]
    img = np.where(face[..., None], skin, img)
    # hair above the forehead, shoulders below
    hair = (rr < 1.25) & (fy < -0.45) & ~((rr < 1.0) & (fy > -0.6))
    img = np.where(
        hair[..., None], np.array([0.22, 0.13, 0.08]) * (0.8 + 0.2 * shade)[..., None], img
    )
    shoulders = (v > 0.8) & (np.abs(u - 0.5) < 0.1 + (v - 0.8) * 1.6)
    img = np.where(
        shoulders[..., None],
        np.array([0.55, 0.12, 0.16]) * (0.9 - 0.3 * np.abs(u - 0.5))[..., None],
        img,
    )
    # eyes and lips
    for ex in (-0.35, 0.35):
        eye = ((fx - ex) ** 2 / 0.02 + (fy + 0.1) ** 2 / 0.006) < 1.0
        img = np.where(eye[..., None], np.array([0.25, 0.18, 0.12]), img)
    lips = (fx**2 / 0.08 + (fy - 0.55) ** 2 / 0.006) < 1.0
    img = np.where(lips[..., None], np.array([0.75, 0.35, 0.35]), img)
    return _to_u8(img)


def procedural_images(w: int, h: int) -> dict[str, np.ndarray]:
    """Three deterministic natural-looking images, each (h, w, 3) uint8 encoded RGB:
    "landscape" (sky gradient, sun, hills, rippled water), "still_life" (shaded fruit on a
    wooden table) and "portrait" (skin-tone face with soft shading). Same output every call."""
    _check(w, h)
    return {
        "landscape": _landscape(w, h, np.random.default_rng(1)),
        "still_life": _still_life(w, h, np.random.default_rng(2)),
        "portrait": _portrait(w, h, np.random.default_rng(3)),
    }
