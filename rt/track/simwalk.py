"""What the tracking camera sees: a face photograph placed in 3-D at known eye positions.

The face is scikit-image's astronaut (``skimage.data.astronaut()``), cut out with a soft
elliptical mask (hair, face, chin) and drawn as a 2.5-D head facing the camera, placed by her
hand-located eyes at a 63 mm interpupillary distance (:mod:`viewcomp.rt.track.simscene`; it
was placed by the cascade's box before, which hid that convention's bias). It is
composited on a noisy, textured grey background, so the detector sees a realistic frame of
the tracking camera; the truth (the eye positions) is known exactly.

- :func:`walk`: a smooth walk in front of the screen (distance 1..3 m, angle 90 +- 40
  degrees), eye positions over time.
- :func:`render_frame`: one camera frame with faces at given eyes.
- :func:`write_walk`: a walk as an image sequence (``frame_00000.png`` ...), ``truth.csv``
  (``seconds,x,y,z``) and a ``rig.toml`` with its ``[tracker]``, each written atomically.
- :func:`walk_camera`: the simulated webcam: 1280x720, 90 degrees horizontal field of view,
  at the screen's top edge looking at the audience.
"""

from __future__ import annotations

import functools
import math
from pathlib import Path

import cv2
import numpy as np

from viewcomp.calib.io.atomic import atomic_path, write_text_atomic
from viewcomp.calib.world.eye import eye_from_angle
from viewcomp.calib.world.rig import Device, Rig, default_rig, rig_to_toml
from viewcomp.rt.track.pose import EYE_ROW, FACE_WIDTH, boxes_from_eyes
from viewcomp.rt.track.simscene import Person, finish, render_person

# The astronaut's face in the 512x512 photograph: the detector's box width (pixels; mean of
# the LBP cascade's boxes 99, 104 and 101 from detectMultiScale(gray, f, 3) for f = 1.05,
# 1.1 and 1.2) and the midpoint of her eyes (pixels, x right, y down).
ASTRONAUT_BOX_PX = 101.0
ASTRONAUT_EYES = (225.0, 102.5)
# The cut-out: an ellipse (centre, half-axes, pixels) around hair, face and chin.
_CUT_CENTRE = (224.0, 118.0)
_CUT_AXES = (88.0, 108.0)


def walk_camera() -> Device:
    """The simulated tracking camera: 1280x720, fov_y 58.7 degrees (90 horizontal), at the
    screen's top edge (0, 0.35, 0.02) m looking at (0, 0.15, 2) m."""
    fov_y = 2.0 * math.degrees(math.atan(math.tan(math.radians(45.0)) * 720 / 1280))
    return Device(
        resolution=(1280, 720),
        position=(0.0, 0.35, 0.02),
        look_at=(0.0, 0.15, 2.0),
        up=(0.0, 1.0, 0.0),
        fov_y=round(fov_y, 3),
    )


def walk_rig() -> Rig:
    """The example rig of docs/INTERFACES.md with :func:`walk_camera` as its ``[tracker]``."""
    from dataclasses import replace

    return replace(default_rig(), tracker=walk_camera())


def walk(
    seconds: float = 12.0,
    fps: float = 30.0,
    near: float = 1.0,
    far: float = 3.0,
    half_angle: float = 40.0,
    height: float = 0.15,
) -> tuple[np.ndarray, np.ndarray]:
    """A smooth walk: the viewing angle swings 90 +- ``half_angle`` degrees once, the distance
    from the screen centre goes between ``near`` and ``far`` metres twice, the eye height
    bobs 3 cm around ``height``.

    Returns:
        times (n,) seconds from 0 at ``fps``, and eyes (n, 3) metres (world frame).
    """
    n = max(1, round(seconds * fps))
    t = np.arange(n) / fps
    phase = 2.0 * math.pi * t / seconds
    theta = 90.0 + half_angle * np.sin(phase)  # degrees
    mid, amp = (near + far) / 2.0, (far - near) / 2.0
    d = mid - amp * np.cos(2.0 * phase + 0.6)
    y = height + 0.03 * np.sin(3.0 * phase)
    return t, eye_from_angle(theta, d, y)


@functools.lru_cache(maxsize=1)
def _face_rgba() -> np.ndarray:
    """The astronaut cut out: (512, 512, 4) float32 BGR + alpha in 0..1."""
    from skimage.data import astronaut

    bgr = astronaut()[:, :, ::-1].astype(np.float32) / 255.0
    yy, xx = np.mgrid[0:512, 0:512].astype(np.float32)
    r = ((xx - _CUT_CENTRE[0]) / _CUT_AXES[0]) ** 2 + ((yy - _CUT_CENTRE[1]) / _CUT_AXES[1]) ** 2
    alpha = np.clip((1.15 - r) / 0.3, 0.0, 1.0)  # soft edge
    return np.dstack([bgr, alpha]).astype(np.float32)


def background(size: tuple[int, int], seed: int = 0) -> np.ndarray:
    """A room-like background (h, w, 3) float32 BGR in 0..1: grey with smooth blotches."""
    w, h = size
    rng = np.random.default_rng(seed)
    coarse = rng.uniform(0.25, 0.65, (9, 16, 3)).astype(np.float32)
    return cv2.resize(coarse, (w, h), interpolation=cv2.INTER_CUBIC)


def astronaut_person() -> Person:
    """The astronaut as a :class:`~viewcomp.rt.track.simscene.Person`: pupils and nose tip
    located by hand on the 512x512 photograph (not by a detector)."""
    from skimage.data import astronaut

    image = np.ascontiguousarray(astronaut()[:, :, ::-1])
    return Person.annotated("astronaut", image, ((204.0, 101.0), (246.0, 104.0)),
                            (222.0, 126.0), (*_CUT_CENTRE, *_CUT_AXES))  # fmt: skip


def render_frame(
    device: Device,
    eyes: np.ndarray,
    back: np.ndarray,
    rng: np.random.Generator,
    face_width: float = FACE_WIDTH,
    noise: float = 0.01,
) -> np.ndarray:
    """One frame of ``device`` with the astronaut's head at each eye (K, 3) metres, over
    ``back``: placed by her eyes at a 63 mm interpupillary distance, facing the camera
    (:func:`viewcomp.rt.track.simscene.render_person`); ``face_width`` is unused (the
    cascade's box convention no longer places the test face).

    Returns:
        (h, w, 3) uint8 BGR at the device's resolution, with Gaussian noise of ``noise``
        (0..1 units) added; heads nearer the camera cover those behind.
    """
    person = astronaut_person()
    out = back.copy()
    e = np.asarray(eyes, np.float64).reshape(-1, 3)
    depth = np.linalg.norm(e - np.asarray(device.position), axis=1)
    for i in np.argsort(-depth):  # far to near
        if np.all(np.isfinite(device.project(e[i][None]))):  # in front of the camera
            out = render_person(out, device, person, e[i])
    return finish(out, rng, noise)


def render_card_frame(
    device: Device,
    eyes: np.ndarray,
    back: np.ndarray,
    rng: np.random.Generator,
    face_width: float = FACE_WIDTH,
    noise: float = 0.01,
) -> np.ndarray:
    """One frame of ``device`` with a flat face at each eye (K, 3) metres, over ``back``,
    sized by the cascade's box convention (a box ``face_width`` wide; the eyes at ``EYE_ROW``
    of it): for the cascade fallback's own tests (its templates), never to judge ranging.

    Returns:
        (h, w, 3) uint8 BGR at the device's resolution, with Gaussian noise of ``noise``
        (0..1 units) added; faces nearer the camera cover those behind.
    """
    face = _face_rgba()
    out = back.copy()
    h, w = out.shape[:2]
    boxes = boxes_from_eyes(device, eyes, face_width, EYE_ROW)
    for b in boxes[np.argsort(-boxes[:, 2])]:  # far to near
        if not np.all(np.isfinite(b)):
            continue
        s = b[2] / ASTRONAUT_BOX_PX  # source pixels -> frame pixels
        u, v = b[0] + 0.5 * b[2], b[1] + EYE_ROW * b[3]  # where the eyes' midpoint goes
        src = cv2.GaussianBlur(face, (0, 0), sigmaX=max(0.5 / s - 0.4, 0.01)) if s < 1 else face
        m = np.array([[s, 0.0, u - s * ASTRONAUT_EYES[0]], [0.0, s, v - s * ASTRONAUT_EYES[1]]])
        warped = cv2.warpAffine(
            src, m, (w, h), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0
        )
        a = warped[:, :, 3:4]
        out = out * (1.0 - a) + warped[:, :, :3] * a
    out = out + rng.normal(0.0, noise, out.shape).astype(np.float32)
    return np.clip(out * 255.0 + 0.5, 0, 255).astype(np.uint8)


def render_walk(
    device: Device,
    eyes: np.ndarray,
    seed: int = 0,
    face_width: float = FACE_WIDTH,
    by_box: bool = False,
) -> list[np.ndarray]:
    """One frame per row of ``eyes`` ((n, 3), or (n, K, 3) for K viewers at once); ``by_box``:
    flat faces placed by the cascade's box convention (:func:`render_card_frame`)."""
    rng = np.random.default_rng(seed)
    back = background(device.resolution, seed)
    e = np.asarray(eyes, np.float64)
    e = e[:, None, :] if e.ndim == 2 else e
    draw = render_card_frame if by_box else render_frame
    return [draw(device, row, back, rng, face_width) for row in e]


def write_walk(
    folder: str | Path,
    seconds: float = 12.0,
    fps: float = 30.0,
    seed: int = 0,
    frames: int | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Write the walk of :func:`walk` seen by :func:`walk_camera` into ``folder`` (created):
    ``frame_00000.png`` ..., ``truth.csv`` (``seconds,x,y,z``) and ``rig.toml``; only its
    first ``frames`` frames when given.

    Returns:
        times (n,) and eyes (n, 3) as :func:`walk` gives them.
    """
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    device = walk_camera()
    times, eyes = walk(seconds, fps)
    times, eyes = times[:frames], eyes[:frames]
    for i, frame in enumerate(render_walk(device, eyes, seed)):
        with atomic_path(out / f"frame_{i:05d}.png") as tmp:
            if not cv2.imwrite(str(tmp), frame):
                raise OSError(f"{out}: cannot write frame_{i:05d}.png")
    rows = ["seconds,x,y,z", *(f"{t:.6f},{e[0]:.6f},{e[1]:.6f},{e[2]:.6f}"
                               for t, e in zip(times, eyes, strict=True))]  # fmt: skip
    write_text_atomic(out / "truth.csv", "\n".join(rows) + "\n")
    write_text_atomic(out / "rig.toml", rig_to_toml(walk_rig()))
    return times, eyes
