"""People placed in the tracking camera by their eyes: photographs as 2.5-D heads.

A test that ranges faces must not place them with the detector it tests. Here a person is a
photograph whose eyes and nose tip were located once by hand (:class:`Person`: pixels), and
the truth is anatomical: the eyes are ``ipd`` metres apart (63 mm, the adult mean), the
head's midpoint between the eyes is at a known 3-D position, facing the camera's centre (or a
point on the screen, as a viewer watching the picture does, nodding against the camera above
it) and turned by a known yaw.

A flat photograph turned in 3-D would be a poor head: its nose does not move against its eyes
(a real head's does: that is how a turn is seen), so the photograph is painted on a relief
(:mod:`viewcomp.rt.track.simrelief`: ``Person.relief``, the model's cylinder and nose ridge, or
a scanned face's measured surface), in the head's own frame (the photograph's roll taken out,
the pupils one IPD apart on its lateral axis, at depth 0), the nose tip 0.55-0.57 IPD in front
of the pupils as a real one is (MediaPipe's canonical face model: 0.57-0.59; menpo3d's scanned
head: 0.57), not as the tracker's model has it (``anatomy.NOSE_DEPTH``, which also allows for
how far out YuNet puts a nose). The photograph is taken as an orthographic view of that head
turned by its own yaw (``Person.yaw``: the turn at which the relief puts the hand-marked nose
tip on the face's midline, :func:`photo_turn`; the tracker's own nose model is not used to
make the test's heads), each of its pixels followed along its ray to the surface it sees
(:func:`seen_lat`: the nearest where a ray meets the relief more than once). The head is
forward-mapped (splatted, far to near) into the frame; what no photograph pixel landed on
inside the head's outline, and the surfaces the photograph saw at a slant of more than 70
degrees (the far side of a nose it saw turned), are filled in from around. Light is scaled by
``gain`` (dim rooms), and an ``occluder`` rectangle (a hand, a cup: fractions of the face's
size) may be drawn over the face.

A head drawn far from its photograph's own turn keeps the nose's look as photographed (its
shading and outline are painted on the relief), and what the photograph did not see (a cheek
and ear turned toward the camera) is filled in from around. A head scanned in 3-D has no such
limit (:mod:`viewcomp.rt.track.simscan`, which draws through :func:`splat` too).

The frame is delivered by an ideal camera (:func:`finish`: a little noise, 8 bits) or by the
calibration's emulated webcam (:func:`through_webcam`: the same sensor and processing that
:mod:`viewcomp.calib.emu` gives the captures).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.optimize import brentq

from viewcomp.calib.emu.camera import develop_image, optics
from viewcomp.calib.emu.profiles import WEBCAM
from viewcomp.calib.world.response import parse_response
from viewcomp.calib.world.rig import Device
from viewcomp.rt.track.anatomy import IPD
from viewcomp.rt.track.simrelief import HEAD_RADIUS, MODEL, Relief

# A photograph's pixel of a surface it saw at a slant covers more of it: drawn where one
# spreads over at most this many times its size (a slant of 70 degrees)
SLANT_STRETCH = 2.9


@dataclass
class Person:
    """A photograph of a person, hand-annotated.

    ``image`` (h, w, 3) uint8 BGR; ``eyes`` (2, 2) pixels (x right, y down) of the pupil
    centres, the eye on the image's left first; ``nose`` (2,) pixels, the nose tip; ``cut``:
    an ellipse (cx, cy, ax, ay) pixels around the head (the rest is transparent); ``yaw``:
    the photographed head's own turn, radians, positive with the nose toward the image's
    right (:func:`photo_turn`); ``relief``: the surface the photograph is painted on
    (:mod:`viewcomp.rt.track.simrelief`).
    """

    name: str
    image: np.ndarray
    eyes: np.ndarray
    nose: np.ndarray
    cut: tuple[float, float, float, float]
    yaw: float = 0.0
    relief: Relief = MODEL

    @staticmethod
    def annotated(
        name: str,
        image: np.ndarray,
        eyes: tuple[tuple[float, float], tuple[float, float]],
        nose: tuple[float, float],
        cut: tuple[float, float, float, float],
        relief: Relief = MODEL,
    ) -> Person:
        """A person whose own head turn follows from the hand-marked nose: the turn at which
        the head :func:`render_person` makes of the photograph on ``relief`` has its nose tip
        on its midline (:func:`photo_turn`)."""
        e = np.asarray(eyes, np.float64)
        n = np.asarray(nose, np.float64)
        return Person(name, image, e, n, cut, photo_turn(e, n, relief), relief)

    @property
    def roll(self) -> float:
        """The eye line's angle in the photograph, radians (image axes: x right, y down)."""
        d = self.eyes[1] - self.eyes[0]
        return float(np.arctan2(d[1], d[0]))

    def posed(self, yaw: float) -> tuple[Person, float]:
        """:func:`posed` of this person."""
        return posed(self, yaw)

    def render(
        self, frame: np.ndarray, device: Device, eye: np.ndarray, turn: float = 0.0,
        gain: float = 1.0, occluder: tuple[float, float, float, float] | None = None,
        look: np.ndarray | None = None,
    ) -> np.ndarray:  # fmt: skip
        """:func:`render_person` of this person (63 mm between the eyes)."""
        return render_person(frame, device, self, eye, turn, IPD, gain, occluder, look)

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
            self.relief.mirrored(),
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


def _aligned(
    eyes: np.ndarray, u: np.ndarray, v: np.ndarray, s: float
) -> tuple[np.ndarray, np.ndarray]:
    """Photograph pixels (u, v) as metres (``s`` per pixel) in the photograph's plane: x
    along the eye line (toward the eye on the image's right), y across it toward the
    forehead; origin the eyes' midpoint. A photograph's roll is taken out, so the head turns
    about its own vertical."""
    mid = eyes.mean(axis=0)
    d = (eyes[1] - eyes[0]) / np.linalg.norm(eyes[1] - eyes[0])
    du, dv = np.asarray(u, np.float64) - mid[0], np.asarray(v, np.float64) - mid[1]
    return (du * d[0] + dv * d[1]) * s, (du * d[1] - dv * d[0]) * s


def _nose_tip(
    eyes: np.ndarray, nose: np.ndarray, yaw0: float, ipd: float, relief: Relief
) -> tuple[float, float]:
    """(lateral, up) metres from the eyes' midpoint of the nose tip ``nose`` (2,) pixels of a
    photograph with pupils ``eyes`` (2, 2) pixels, taken of the head turned by ``yaw0``: where
    the photograph's ray through it meets the relief, which is itself placed by the tip (a
    fixed point). NaN lateral where the ray passes beside the head."""
    c = np.cos(yaw0)
    s = ipd * c / float(np.linalg.norm(eyes[1] - eyes[0]))
    xn, yn = (float(w) for w in _aligned(eyes, nose[0], nose[1], s))
    ln = xn / c
    for _ in range(30):
        seen = seen_lat(relief, np.array([xn]), np.array([yn]), (ln, yn), yaw0, ipd)
        ln, was = float(seen[0]), ln
        if not abs(ln - was) >= 1e-12 * ipd:  # converged, or beside the head (NaN)
            break
    return ln, yn


# The photograph's view of a relief is tabulated on rows ROW_STEP IPD apart, each sampled at
# LAT_SAMPLES points across the head, before each pixel's point is polished by Newton's method
ROW_STEP = 0.01
LAT_SAMPLES = 1024


def seen_lat(
    relief: Relief,
    x: np.ndarray,
    y: np.ndarray,
    tip: tuple[float, float],
    yaw0: float,
    ipd: float,
) -> np.ndarray:
    """(N,) metres: the lateral coordinate of the surface point an orthographic photograph of
    the head turned by ``yaw0`` sees at ``x`` (N,) metres along its eye line (x = lateral
    cos(yaw0) + forward sin(yaw0)) and ``y`` (N,) metres up. A ray may meet the relief more
    than once (a nose seen turned); the nearest meeting is the one seen: along each row
    sampled across the head, a point is seen where no point nearer the photograph's side
    reaches as far along the eye line (a horizon), and the seen points are interpolated;
    then Newton's method makes each pixel's exact on its own row, kept where it converges
    near the interpolated point. NaN where the ray passes beside the head, or where neither
    is within 0.01 IPD of the ray (a pixel on a fold's edge: 9 in 10000 of luispedro's)."""
    c, sn = np.cos(yaw0), np.sin(yaw0)
    lim = 0.999 * HEAD_RADIUS * ipd
    lats = np.linspace(-lim, lim, LAT_SAMPLES)
    step = ROW_STEP * ipd
    lo = float(np.min(y)) - step
    rows = lo + step * np.arange(int(np.ceil((float(np.max(y)) + step - lo) / step)) + 1)
    reach = lats * c + relief.forward(lats[None, :], rows[:, None], tip, ipd) * sn
    if sn >= 0:  # the photograph sees the head from the image's left: a horizon from there
        seen = reach >= np.maximum.accumulate(reach, axis=1)
    else:
        seen = reach <= np.minimum.accumulate(reach[:, ::-1], axis=1)[:, ::-1]
    j = np.clip(np.rint((y - lo) / step).astype(np.int64), 0, len(rows) - 1)
    order = np.argsort(j, kind="stable")  # the pixels row by row
    bounds = np.searchsorted(j[order], np.arange(len(rows) + 1))
    lat = np.empty(len(x))
    miss = np.zeros(len(x), bool)
    for r in range(len(rows)):
        q = order[bounds[r] : bounds[r + 1]]
        if len(q):
            ends = reach[r][seen[r]]
            lat[q] = np.interp(x[q], ends, lats[seen[r]])
            miss[q] = (x[q] < ends[0]) | (x[q] > ends[-1])
    fwd = relief.forward
    g0 = lat * c + fwd(lat, y, tip, ipd) * sn - x
    out, g, h = lat.copy(), g0, 1e-4 * ipd
    for _ in range(6):  # Newton's method: converged in 2-3 steps where the photograph saw well
        slope = (fwd(out + h, y, tip, ipd) - fwd(out - h, y, tip, ipd)) / (2 * h)
        out = out - g / np.maximum(c + slope * sn, 0.05)
        g = out * c + fwd(out, y, tip, ipd) * sn - x
        if not np.any(np.abs(g) >= 1e-7 * ipd):
            break
    good = (np.abs(g) < 1e-7 * ipd) & (np.abs(out - lat) < 2.0 * step)
    miss |= ~good & (np.abs(g0) > 0.01 * ipd)  # between a fold's two sides: not placed
    return np.where(miss, np.nan, np.where(good, out, lat))


def photo_points(
    person: Person, u: np.ndarray, v: np.ndarray, yaw0: float | None = None, ipd: float = IPD
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The head a photograph becomes, in the head's own frame: photograph pixels (u, v) as
    (lateral, up, forward) metres from the eyes' midpoint, the photograph taken of the head
    turned by ``yaw0`` radians (None: ``person.yaw``) and its roll taken out (:func:`_aligned`):
    the pupils at (-``ipd`` / 2, 0, 0) and (``ipd`` / 2, 0, 0), the surface ``person.relief``'s
    (the photograph's ray through each pixel followed to the surface it sees,
    :func:`seen_lat`); and how the photograph saw the surface there: its length per length
    across the head (1 face-on, cos(``yaw0``) where the face is flat). Lateral and forward
    are NaN (and the length 0) where a pixel's ray passes beside the head."""
    y0 = person.yaw if yaw0 is None else yaw0
    c, sn = np.cos(y0), np.sin(y0)
    s = ipd * c / float(np.linalg.norm(person.eyes[1] - person.eyes[0]))
    x, y = _aligned(person.eyes, u, v, s)  # x = lateral cos(y0) + forward sin(y0)
    tip = _nose_tip(person.eyes, person.nose, y0, ipd, person.relief)
    x, y = np.broadcast_arrays(x, y)
    lat = seen_lat(person.relief, x.ravel(), y.ravel(), tip, y0, ipd).reshape(x.shape)
    miss = np.isnan(lat)
    on = np.where(miss, 0.0, lat)
    h = 1e-4 * ipd
    fwd = person.relief.forward
    slope = (fwd(on + h, y, tip, ipd) - fwd(on - h, y, tip, ipd)) / (2 * h)
    return lat, y, np.where(miss, np.nan, fwd(on, y, tip, ipd)), np.where(miss, 0.0, c + slope * sn)


def photo_turn(eyes: np.ndarray, nose: np.ndarray, relief: Relief = MODEL) -> float:
    """The photographed head's own turn, radians (positive: the nose toward the image's
    right), from its pupils ``eyes`` (2, 2) and nose tip ``nose`` (2,) pixels: the turn at
    which the head :func:`photo_points` makes of it on ``relief`` has the nose tip on its
    midline (the nose tip stands where the relief puts it, 0.56-0.57 IPD in front of the
    eyes). ValueError for a nose too far aside for a head turned under 50 degrees."""
    e, n = np.asarray(eyes, np.float64), np.asarray(nose, np.float64)

    def off_midline(y0: float) -> float:
        return _nose_tip(e, n, y0, 1.0, relief)[0]

    lim = np.radians(50.0)
    if not off_midline(-lim) * off_midline(lim) <= 0:  # same sides, or beside the head
        raise ValueError("the nose tip is too far aside for a head turned under 50 degrees")
    return float(brentq(off_midline, -lim, lim, xtol=1e-10))


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


def head_axes(
    device: Device, eye: np.ndarray, turn: float, look: np.ndarray | None, roll: float = 0.0
) -> np.ndarray:
    """(3, 3): directions in a head's own frame (lat, up, fwd: its columns) to the world's,
    for a head at ``eye`` facing ``look`` (:func:`head_frame`), turned ``turn`` radians about
    its own vertical (positive: the nose toward the image's right), then rolled ``roll``
    radians in the face's plane."""
    c, s = np.cos(turn), np.sin(turn)
    cr, sr = np.cos(roll), np.sin(roll)
    yaw = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
    tilt = np.array([[cr, sr, 0.0], [-sr, cr, 0.0], [0.0, 0.0, 1.0]])
    return head_frame(device, np.asarray(eye, np.float64), look).T @ tilt @ yaw


def placed(
    device: Device,
    person: Person,
    eye: np.ndarray,
    turn: float,
    look: np.ndarray | None,
    lat: np.ndarray,
    up: np.ndarray,
    forward: np.ndarray,
) -> np.ndarray:
    """(..., 3) metres, world frame: points of the head in its own frame (:func:`photo_points`:
    ``lat``, ``up``, ``forward``, each (...)) for the head of :func:`render_person` (its eyes'
    midpoint at ``eye``, facing ``look``, turned ``person.yaw`` + ``turn`` about its own
    vertical, rolled as photographed)."""
    axes = head_axes(device, eye, person.yaw + turn, look, person.roll)
    return np.asarray(eye, np.float64) + np.stack([lat, up, forward], axis=-1) @ axes.T


def drawn_landmarks(
    device: Device,
    person: Person,
    eye: np.ndarray,
    turn: float = 0.0,
    look: np.ndarray | None = None,
    ipd: float = IPD,
) -> np.ndarray:
    """(3, 3) metres, world frame: the pupils (the eye on the photograph's left first) and the
    nose tip of the head :func:`render_person` draws with the same arguments."""
    marks = np.vstack([person.eyes, person.nose[None]])
    lat, up, fwd, _ = photo_points(person, marks[:, 0], marks[:, 1], None, ipd)
    return placed(device, person, eye, turn, look, lat, up, fwd)


def render_person(
    frame: np.ndarray,
    device: Device,
    person: Person,
    eye: np.ndarray,
    turn: float = 0.0,
    ipd: float = IPD,
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
    lat, y, fwd, seen = photo_points(person, uu, vv, None, ipd)
    alpha[np.isnan(lat) | (np.abs(lat) > 0.98 * HEAD_RADIUS * ipd)] = 0.0  # beyond the head
    lat, fwd = np.nan_to_num(lat), np.nan_to_num(fwd)
    # where the photograph saw the surface at too much of a slant to draw it (one photograph
    # pixel spreading over more than SLANT_STRETCH), its colour is filled in from around
    unseen = (seen < 1.0 / SLANT_STRETCH).ravel()
    pts = placed(device, person, e, turn, look, lat, y, fwd)
    uv = device.project(pts.reshape(-1, 3))
    sight = np.asarray(device.position, np.float64) - e  # from the head to the camera
    sight /= np.linalg.norm(sight)
    depth = (pts.reshape(-1, 3) - np.asarray(device.position)) @ (-sight)
    colour = np.concatenate([src.reshape(-1, 3) * gain, alpha.reshape(-1, 1)], axis=1)
    return splat(frame, uv, depth, colour, ~unseen)


def splat(
    frame: np.ndarray, uv: np.ndarray, depth: np.ndarray, colour: np.ndarray, known: np.ndarray
) -> np.ndarray:
    """``frame`` (h, w, 3) with points at ``uv`` (M, 2) pixels drawn over it, far to near
    (``depth`` (M,)): ``colour`` (M, 4) colour and coverage (0: not drawn), whose colour is
    ``known`` (M,) bool or filled in from around (:func:`_fill_holes`). A new array."""
    h, w = frame.shape[:2]
    pu = np.rint(uv[:, 0]).astype(np.int64)
    pv = np.rint(uv[:, 1]).astype(np.int64)
    keep = (colour[:, 3] > 0) & np.all(np.isfinite(uv), axis=1)
    keep &= (pu >= 0) & (pu < w) & (pv >= 0) & (pv < h)
    order = np.flatnonzero(keep)
    order = order[np.argsort(-depth[order], kind="stable")]  # far first: near ones win
    out = frame.copy()
    if len(order) == 0:
        return out
    u0, v0 = int(pu[order].min()), int(pv[order].min())
    size = (int(pv[order].max()) - v0 + 1, int(pu[order].max()) - u0 + 1)
    layer = np.zeros((*size, 4), np.float32)
    layer[pv[order] - v0, pu[order] - u0] = colour[order]
    seen = np.zeros(size, bool)
    seen[pv[order] - v0, pu[order] - u0] = known[order]  # the nearest point's
    _fill_holes(layer, seen)
    region = out[v0 : v0 + size[0], u0 : u0 + size[1]]
    region[:] = region * (1.0 - layer[..., 3:]) + layer[..., :3] * layer[..., 3:]
    return out


def _fill_holes(layer: np.ndarray, known: np.ndarray) -> None:
    """Fills in, in place, the pixels of ``layer`` (h, w, 4: colour and coverage, zero where
    nothing landed) inside the head's outline whose colour is not ``known`` (h, w): where
    nothing landed (one photograph pixel spread over several frame pixels: the turn shows
    what the photograph saw at a slant) and where the photograph did not see the surface
    (the side of a nose it saw from the other side). The outline is a 5x5 closing of what
    landed; each round gives the unknown pixels next to known ones their mean."""
    inside = cv2.morphologyEx(
        (layer[..., 3] > 0).astype(np.uint8), cv2.MORPH_CLOSE, np.ones((5, 5), np.uint8)
    ).astype(bool)
    known = known & inside
    while True:
        hole = inside & ~known
        weight = cv2.boxFilter(known.astype(np.float32), -1, (3, 3), normalize=False)
        fill = hole & (weight > 0)
        if not fill.any():
            return
        total = cv2.boxFilter(layer * known[..., None], -1, (3, 3), normalize=False)
        layer[fill] = total[fill] / weight[fill][:, None]
        known = known | fill


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
