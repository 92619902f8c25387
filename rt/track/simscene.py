"""People placed in the tracking camera by their eyes: photographs as 2.5-D heads.

A test that ranges faces must not place them with the detector it tests. Here a person is a
photograph whose eyes and nose tip were located once by hand (:class:`Person`: pixels), and
the truth is anatomical: the eyes are ``ipd`` metres apart (63 mm, the adult mean), the
head's midpoint between the eyes is at a known 3-D position, facing the camera's centre (or a
point on the screen, as a viewer watching the picture does, nodding against the camera above
it) and turned by a known yaw.

A flat photograph turned in 3-D would be a poor head: its nose does not move against its eyes
(a real head's does: that is how a turn is seen), so the photograph gets a relief: the face
plane (tilted by the photograph's own head turn, ``Person.yaw``), rounded as a cylinder of
82 mm radius (the far cheek recedes when the head turns), plus a nose ridge rising to the nose
tip ``nose_depth`` IPD in front of the eyes (:mod:`viewcomp.rt.track.anatomy`'s
model). The relief is forward-mapped (splatted, far to near) into the frame; light is scaled
by ``gain`` (dim rooms), and an ``occluder`` rectangle (a hand, a cup: fractions of the face's
size) may be drawn over the face.

The nose ridge rises ``nose_depth`` (0.4 IPD, the tracker's default) above the face plane,
and the head's roundness adds about 0.07 IPD at the centre line, so the nose tip of a
frontal photograph stands 0.46-0.47 IPD in front of the eyes: from exact landmarks the
tracker reads a head turned 45 degrees 9-10 % short (docs/INTERFACES.md, "Measured").

The frame is delivered by an ideal camera (:func:`finish`: a little noise, 8 bits) or by the
calibration's emulated webcam (:func:`through_webcam`: the same sensor and processing that
:mod:`viewcomp.calib.emu` gives the captures).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from viewcomp.calib.emu.camera import develop_image, optics
from viewcomp.calib.emu.profiles import WEBCAM
from viewcomp.calib.world.response import parse_response
from viewcomp.calib.world.rig import Device
from viewcomp.rt.track.anatomy import IPD, NOSE_DEPTH

HEAD_RADIUS = 1.3  # the head's roundness: a cylinder of this radius, in IPDs (82 mm)


@dataclass
class Person:
    """A photograph of a person, hand-annotated.

    ``image`` (h, w, 3) uint8 BGR; ``eyes`` (2, 2) pixels (x right, y down) of the pupil
    centres, the eye on the image's left first; ``nose`` (2,) pixels, the nose tip; ``cut``:
    an ellipse (cx, cy, ax, ay) pixels around the head (the rest is transparent); ``yaw``:
    the photographed head's own turn, radians, positive with the nose toward the image's
    right (from the nose's offset: the same model as the tracker's, see the module's note).
    """

    name: str
    image: np.ndarray
    eyes: np.ndarray
    nose: np.ndarray
    cut: tuple[float, float, float, float]
    yaw: float = 0.0

    @staticmethod
    def annotated(
        name: str,
        image: np.ndarray,
        eyes: tuple[tuple[float, float], tuple[float, float]],
        nose: tuple[float, float],
        cut: tuple[float, float, float, float],
        nose_depth: float = NOSE_DEPTH,
    ) -> Person:
        """A person whose own head turn follows from the hand-marked nose."""
        e = np.asarray(eyes, np.float64)
        n = np.asarray(nose, np.float64)
        d = e[1] - e[0]
        r = float((n - e.mean(axis=0)) @ d / (d @ d))
        return Person(name, image, e, n, cut, float(np.arctan2(r, nose_depth)))

    def mirrored(self) -> Person:
        """The photograph mirrored left to right: the same person turned the other way."""
        w = self.image.shape[1]
        flip = np.array([-1.0, 1.0])
        shift = np.array([w - 1.0, 0.0])
        eyes = shift + flip * self.eyes[::-1]  # the eye on the image's left first again
        cx, cy, ax, ay = self.cut
        return Person(
            self.name,
            np.ascontiguousarray(self.image[:, ::-1]),
            eyes,
            shift + flip * self.nose,
            (w - 1.0 - cx, cy, ax, ay),
            -self.yaw,
        )


#: A photograph of a head turned by more than this (radians) is drawn turned the other way
#: from its mirror image: its relief carries the photographed face, nose and shading
#: included, so turning it across frontal to the other side paints the nose on the wrong
#: side of the head (YuNet then reads a head turned 45 degrees as nearly frontal).
MIRROR_BEYOND = np.radians(20.0)


def posed(person: Person, yaw: float) -> tuple[Person, float]:
    """The photograph and the turn (radians, :func:`render_person`'s ``turn``) that draw
    ``person`` with a total yaw of ``yaw`` radians: a photographed turn of more than
    MIRROR_BEYOND toward the side opposite ``yaw`` is drawn from the mirror image."""
    if abs(person.yaw) > MIRROR_BEYOND and person.yaw * yaw < 0:
        person = person.mirrored()
    return person, yaw - person.yaw


def _relief(
    x: np.ndarray, y: np.ndarray, nose: np.ndarray, yaw0: float, ipd: float, depth: float
) -> np.ndarray:
    """Depth (toward the photographer, metres) of the face at photo-plane point (x, y) metres
    (origin at the eyes' midpoint, y up): the face plane tilted by ``yaw0`` plus a nose
    ridge from between the eyes (35 % of the tip's height) to the tip at ``nose``."""
    b = depth * ipd / np.cos(yaw0)  # the ridge's height above the tilted plane at the tip
    xn, yn = nose
    t = np.clip(y / yn, 0.0, 1.0) if yn < 0 else np.zeros_like(y)
    cx = t * xn  # the ridge runs from between the eyes to the tip
    along = np.where(
        y > 0,
        0.35 * np.exp(-0.5 * (y / (0.12 * ipd)) ** 2),
        np.where(y >= yn, 0.35 + 0.65 * t, np.exp(-0.5 * ((y - yn) / (0.12 * ipd)) ** 2)),
    )
    across = np.exp(-0.5 * ((x - cx) / (0.28 * ipd)) ** 2)
    # the head's roundness: a vertical cylinder of radius 1.3 IPD (82 mm) through the eyes,
    # so the far cheek recedes and the outline moves when the head turns
    r = HEAD_RADIUS * ipd
    u = np.clip(np.abs(x * np.cos(yaw0)) / r, 0.0, 0.999)  # across the face plane
    round_ = r * (np.sqrt(1.0 - u**2) - np.sqrt(1.0 - (0.5 * ipd / r) ** 2))
    return -x * np.tan(yaw0) + b * along * across + round_ / np.cos(yaw0)


def head_frame(device: Device, eye: np.ndarray, look: np.ndarray | None = None) -> np.ndarray:
    """(3, 3) rows side, up, back: a head at ``eye`` facing ``look`` (3,) metres (None: the
    camera's centre), upright (its side along the camera's image x, level across the face):
    ``back`` points where the face looks; a head looking below or above the camera is seen
    nodding (its eye-to-mouth length foreshortened, the eyes' separation not)."""
    target = np.asarray(device.position if look is None else look, np.float64)
    back = target - eye
    back /= np.linalg.norm(back)
    rot, _ = device.pose()
    side = rot[0] - (rot[0] @ back) * back
    side /= np.linalg.norm(side)
    return np.stack([side, np.cross(back, side), back])


def render_person(
    frame: np.ndarray,
    device: Device,
    person: Person,
    eye: np.ndarray,
    turn: float = 0.0,
    ipd: float = IPD,
    nose_depth: float = NOSE_DEPTH,
    gain: float = 1.0,
    occluder: tuple[float, float, float, float] | None = None,
    look: np.ndarray | None = None,
) -> np.ndarray:
    """``frame`` (h, w, 3) float32 BGR 0..1 with ``person``'s head drawn over it.

    Args:
        device: the tracking camera.
        eye: (3,) metres, world frame: the midpoint of the head's eyes.
        turn: radians the head is turned beyond its photographed turn (positive: the nose
            toward the image's right); the head's total yaw is ``person.yaw + turn``.
        ipd: the head's interpupillary distance, metres.
        gain: the face's brightness factor (dim light < 1).
        occluder: (x0, y0, x1, y1) in units of the eyes' separation from the eyes'
            midpoint in the photograph (x right, y down), drawn dark grey over the face.
        look: (3,) metres: the point the head faces before its ``turn`` (None: the
            camera's centre; a viewer watching the screen faces a point on it).

    Returns:
        The frame (a new array).
    """
    e = np.asarray(eye, np.float64)
    img = person.image
    sep_px = float(np.linalg.norm(person.eyes[1] - person.eyes[0]))
    s = ipd * np.cos(person.yaw) / sep_px  # metres per photo pixel
    mid = person.eyes.mean(axis=0)
    # how large a photo pixel lands in the frame: supersample so no holes appear
    rng = float(np.linalg.norm(e - np.asarray(device.position)))
    scale = device.focal() * s / rng  # frame pixels per photo pixel
    k = max(1, int(np.ceil(2.0 * scale)))
    cx, cy, ax, ay = person.cut
    src, x0, y0 = _face_patch(img, person.cut, scale, k)
    hh, ww = src.shape[:2]
    u = x0 + (np.arange(ww) + 0.5) / k - 0.5
    v = y0 + (np.arange(hh) + 0.5) / k - 0.5
    uu, vv = np.meshgrid(u, v)
    alpha = np.clip((1.15 - ((uu - cx) / ax) ** 2 - ((vv - cy) / ay) ** 2) / 0.3, 0.0, 1.0)
    if occluder is not None:
        ox0, oy0, ox1, oy1 = occluder
        du, dv = (uu - mid[0]) / sep_px, (vv - mid[1]) / sep_px
        inside = (du >= ox0) & (du <= ox1) & (dv >= oy0) & (dv <= oy1)
        src[inside] = 0.18
        alpha[inside] = 1.0
    x = (uu - mid[0]) * s
    y = -(vv - mid[1]) * s
    nose = np.array([(person.nose[0] - mid[0]) * s, -(person.nose[1] - mid[1]) * s])
    z = _relief(x, y, nose, person.yaw, ipd, nose_depth)
    alpha[np.abs(x * np.cos(person.yaw)) > 0.98 * HEAD_RADIUS * ipd] = 0.0  # beyond the head
    c, sn = np.cos(turn), np.sin(turn)
    xr, zr = x * c + z * sn, -x * sn + z * c
    side, up, back = head_frame(device, e, look)
    pts = e + xr[..., None] * side + y[..., None] * up + zr[..., None] * back
    uv = device.project(pts.reshape(-1, 3))
    sight = np.asarray(device.position, np.float64) - e  # from the head to the camera
    sight /= np.linalg.norm(sight)
    depth = (pts.reshape(-1, 3) - np.asarray(device.position)) @ (-sight)
    keep = (alpha.ravel() > 0) & np.all(np.isfinite(uv), axis=1)
    h, w = frame.shape[:2]
    pu = np.rint(uv[:, 0]).astype(np.int64)
    pv = np.rint(uv[:, 1]).astype(np.int64)
    keep &= (pu >= 0) & (pu < w) & (pv >= 0) & (pv < h)
    order = np.flatnonzero(keep)
    order = order[np.argsort(-depth[order], kind="stable")]  # far first: near ones win
    out = frame.copy()
    colour = src.reshape(-1, 3)[order] * gain
    a = alpha.ravel()[order, None]
    idx = pv[order], pu[order]
    out[idx] = out[idx] * (1.0 - a) + colour * a
    return out


def _face_patch(
    img: np.ndarray, cut: tuple[float, float, float, float], scale: float, k: int
) -> tuple[np.ndarray, int, int]:
    """The photograph's face cut (cx, cy, ax, ay: centre and half sizes, pixels) as float 0..1,
    low-passed when it lands smaller than a frame pixel (``scale`` frame px per photo px) and
    upsampled ``k`` times; returns it and its top-left photo pixel (x0, y0)."""
    cx, cy, ax, ay = cut
    x0, x1 = int(max(0, cx - ax)), int(min(img.shape[1], cx + ax + 1))
    y0, y1 = int(max(0, cy - ay)), int(min(img.shape[0], cy + ay + 1))
    src = img[y0:y1, x0:x1].astype(np.float32) / 255.0
    if scale < 1.0:  # pre-filter before the photograph is sampled down
        src = np.asarray(
            cv2.GaussianBlur(src, (0, 0), sigmaX=max(0.5 / scale - 0.4, 0.01)), np.float32
        )
    if k > 1:
        src = np.asarray(
            cv2.resize(src, None, fx=k, fy=k, interpolation=cv2.INTER_LINEAR), np.float32
        )
    return src, x0, y0


def finish(frame: np.ndarray, rng: np.random.Generator, noise: float = 0.01) -> np.ndarray:
    """A float frame (0..1) as the camera delivers it: Gaussian noise of ``noise``, uint8."""
    out = frame + rng.normal(0.0, noise, frame.shape).astype(np.float32)
    return np.clip(out * 255.0 + 0.5, 0, 255).astype(np.uint8)


def through_webcam(frame: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A float frame (0..1, BGR, sRGB-encoded: what an ideal camera delivers) as the
    calibration's emulated webcam (:data:`viewcomp.calib.emu.profiles.WEBCAM`) delivers it,
    uint8 BGR: decoded to relative light, then the emulator's own optics and development
    (:func:`viewcomp.calib.emu.camera.optics`, :func:`~viewcomp.calib.emu.camera.develop_image`:
    the lens' blur, a Bayer sensor's shot and read noise from ``rng``, demosaicing, tone
    curve, denoising, sharpening, 8 bits, MJPEG), at unit gain and neutral white balance."""
    light = parse_response("srgb").decode(np.clip(frame[:, :, ::-1], 0.0, 1.0))
    light = optics(np.ascontiguousarray(light, np.float32), WEBCAM)
    rgb = develop_image(light, WEBCAM, 1.0, np.ones(3, np.float32), rng)
    return np.ascontiguousarray(rgb[:, :, ::-1])
