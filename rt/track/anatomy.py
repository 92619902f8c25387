"""A viewer's eye from a face's landmarks: distance from the interpupillary distance.

A detector's box is as wide as its training data made it, not as wide as a face; the two eye
centres are a measure of the head itself. Adults' interpupillary distance (IPD) is 63 mm on
average (about +-6 % between people, one standard deviation), so the image separation of the
eyes, s (in normalised units: radians at the eye), gives the range R = IPD cos(yaw) / s from
the camera's centre to the eyes' midpoint.

Per face (five landmarks, pixels: left eye, right eye, nose tip, mouth corners):

1. Each landmark becomes a ray of the tracking camera (its pose, intrinsics and lens:
   :meth:`viewcomp.calib.world.rig.Device.rays_through`); the rays are projected onto the
   plane at unit distance perpendicular to the eyes' midpoint ray m. This removes the
   stretching of an off-axis face in a wide-angle image and the camera's own tilt.
2. Roll (the eye line's angle in that plane) does not shorten the eyes' separation: the full
   2-D distance s between the eyes is used, and the nose is measured along the eye line.
3. Yaw (the head turned about its vertical axis) shortens s by cos(yaw) and moves the nose
   tip, which stands ``nose_depth`` IPD in front of the eyes, sideways by
   nose_depth IPD sin(yaw): with r = (nose - eyes' midpoint) . eye direction / s,
   tan(yaw) = r / nose_depth and cos(yaw) = 1 / sqrt(1 + tan(yaw)^2). Pitch (nodding) moves
   the nose across the eye line and does not change s; a head that nods and turns shows its
   eye line rolled and its nose reads the turn short (exact landmarks of heads watching the
   screen, turned 45 degrees: 18-39 degrees), which the face height below takes back in part.
4. The eye (the eyes' midpoint) is the camera's centre + R m, in the world frame.

A head turned far is ranged better by a length that a turn does not shorten: the eyes' midpoint
to the mouth's, across the eye line (``height``), which a nod shortens instead. People differ in
it more than in IPD, so it is measured per viewer (:mod:`viewcomp.rt.track.tracker`): on the
frames read frontal (yaw under ``FRONTAL``), its length in metres is ``height`` x the IPD's
range (:func:`face_height`). Both readings assume the viewer watches the picture: the head
faces ``look`` (the screen's centre, the world origin), so the camera above or below it sees
the face nodding by a known angle (:func:`nod`).

The two ranges are combined by what each can be wrong by (:func:`ranged_eyes`). A detector's
nose point may move less than the real tip when the head turns (YuNet's stands 0.72-1.05 as far
out as a hand-marked tip on real photographs along the hand-marked eye line, 0.59-1.00 along
its own), so the turn is read short and the IPD's range
long; a nose deeper than the model's reads it long. ``nose_depth`` is the middle of what the
two allow together (:data:`NOSE_DEPTH`), and the true turn lies between the read one with its
nose offset shrunk to ``NOSE_LAG`` and grown to ``NOSE_LEAD`` times (:func:`turn_bounds`): a
frontal reading leaves the range almost exact, a turned one an interval. The face height's
range is a Gaussian (its relative spread: ``HEIGHT_SPREAD`` for a viewer's own height,
``PRIOR_SPREAD`` for the typical one); the range taken is its mean within that interval (a
truncated Gaussian). Before a viewer's own height is measured (a single frame, a face first
seen turned), the adults' typical height is used the same way (:func:`prior_ranged_eyes`):
``FACE_HEIGHT`` IPD, from anthropometric norms, not from the tracker's test faces.

Error model (docs/INTERFACES.md): the range is proportional to the viewer's true IPD, so a
person whose IPD differs from ``ipd`` by 6 % is ranged 6 % off (x, y scale with it along the
line of sight); a landmark error of e pixels on an eye separation of S pixels gives about
e sqrt(2) / S; a real nose depth 20 % smaller than ``nose_depth`` under-reads the yaw and
ranges 5 % far at 30 degrees of yaw, 10 % at 45. The head is taken as flat across the line
of sight (the near eye's perspective is ignored): within 1.5 % up to 25 degrees, 3 % at 45.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import ndtr

from viewcomp.calib.world.rig import Device

IPD = 0.063  # metres: mean adult interpupillary distance
# How far a detector's nose point stands in front of the pupils, as a fraction of the IPD
# (32 mm): the nose tip's depth, 0.57-0.59 IPD (MediaPipe's canonical face model, a population
# model in centimetres: 0.574 for its nose tip, 0.592 for its most forward point, from the eyes'
# lid centres; menpo3d's scanned head: 0.57), times how far out YuNet puts it against a
# hand-marked tip on real photographs, 0.72-1.05 along the hand-marked eye line: 0.41-0.62,
# whose middle this is. (Along YuNet's own eye line, as a turn is read, 0.59-1.00 on the same
# photographs, bench/bench_nose_photographs.py: 0.34-0.57, whose middle, 0.45, reads the one
# head seen turned in 3-D over-turned, its nose 0.82-0.87 of its tip; docs/INTERFACES.md,
# "What a redrawn photograph cannot show".)
NOSE_DEPTH = 0.5
MAX_YAW = np.radians(60.0)  # a larger estimate is clipped (a nearly profile face)
# A face whose read yaw is under FRONTAL measures its viewer's face height, unless the height
# known so far ranges it NEARER_FROM nearer than its IPD (turned more than its nose says) or
# NEARER_TO farther (an outlier): the height's per-frame scatter is about 5 %, one SD.
FRONTAL = np.radians(15.0)
NEARER_FROM = 0.04
NEARER_TO = 0.12
# The turn the landmarks allow: the nose's offset from the eyes' midpoint is from NOSE_LAG to
# NOSE_LEAD times what NOSE_DEPTH gives: the ends of NOSE_DEPTH's 0.41-0.62, rounded outward.
# (Photographs redrawn at another turn show 0.34-1.84 times the drawn tip's offset,
# docs/INTERFACES.md, "Measured": their painted noses, not YuNet's; not used here.)
NOSE_LAG = 0.8
NOSE_LEAD = 1.25
# The eyes'-midpoint-to-mouth-corners' height of an adult, in IPDs, where the viewer's own is
# not measured yet: nasion to stomion is 72-77 mm in adult norms (women - men; nasal height
# 48-51 mm + upper lip 24-26 mm), the pupils lie about 10 mm below the nasion and the mouth
# corners about 2 mm above the stomion: 60-65 mm, against IPDs of 60-64 mm.
FACE_HEIGHT = 1.0
# The face height's range scatters by about HEIGHT_SPREAD (one SD, relative) frame to frame;
# the typical height's by PRIOR_SPREAD: people differ in it by about 7 % besides.
HEIGHT_SPREAD = 0.05
PRIOR_SPREAD = 0.09
LOOK = (0.0, 0.0, 0.0)  # metres: where viewers look, the screen's centre


@dataclass
class HeadPose:
    """What the landmarks of N faces say: ``eyes`` (N, 3) metres, world frame (the eyes'
    midpoint); ``range`` (N,) metres from the camera's centre (from the IPD); ``yaw`` and
    ``roll`` (N,) radians (yaw positive when the nose points to the image's right);
    ``separation`` (N,) the eyes' separation in normalised units (radians); ``height`` (N,)
    normalised units, the eyes' midpoint to the mouth corners' across the eye line (NaN
    without a mouth); ``rays`` (N, 3) unit vectors from the camera's centre ``origin`` (3,)
    to the eyes; ``nod`` (2, N): (cos a, sin a) of each head as :func:`nod` gives them for the
    ``look`` of :func:`head_pose`; ``ipd`` metres, the interpupillary distance ranged with."""

    eyes: np.ndarray
    range: np.ndarray
    yaw: np.ndarray
    roll: np.ndarray
    separation: np.ndarray
    height: np.ndarray
    rays: np.ndarray
    origin: np.ndarray
    nod: np.ndarray
    ipd: float = IPD

    def take(self, keep: np.ndarray) -> HeadPose:
        """The faces where ``keep`` (N,) bool is true."""
        k = np.asarray(keep, bool)
        return HeadPose(
            self.eyes[k], self.range[k], self.yaw[k], self.roll[k], self.separation[k],
            self.height[k], self.rays[k], self.origin, self.nod[:, k], self.ipd,
        )  # fmt: skip


def head_pose(
    device: Device,
    landmarks: np.ndarray,
    ipd: float = IPD,
    nose_depth: float = NOSE_DEPTH,
    look: tuple[float, float, float] = LOOK,
) -> HeadPose:
    """Eye positions from face landmarks.

    Args:
        device: the tracking camera at the frames' resolution.
        landmarks: (N, 5, 2) pixels (x right, y down): the eye on the image's left, the eye
            on its right, the nose tip, the mouth corners (YuNet's order; the mouth is not
            used). (N, 2, 2) (eyes only) is taken as a frontal face.
        ipd: the viewer's interpupillary distance, metres (> 0).
        nose_depth: the nose tip's depth in front of the eyes, a fraction of ``ipd``.
        look: (3,) metres, where the viewers' heads face (the nod of :class:`HeadPose`).

    Returns:
        :class:`HeadPose` of the N faces.
    """
    if not ipd > 0:
        raise ValueError(f"the interpupillary distance must be > 0 metres, got {ipd}")
    lm = np.asarray(landmarks, np.float64)
    if lm.ndim != 3 or lm.shape[2] != 2 or lm.shape[1] < 2:
        raise ValueError(f"landmarks must have shape (N, 5, 2) or (N, 2, 2), got {lm.shape}")
    n = len(lm)
    origin = np.asarray(device.position, np.float64)
    if n == 0:
        z = np.zeros(0)
        return HeadPose(
            np.zeros((0, 3)), z, z, z, z, z, np.zeros((0, 3)), origin, np.zeros((2, 0)), ipd
        )
    rays = device.rays_through(lm)  # (N, K, 3) unit, world
    m = rays[:, 0] + rays[:, 1]
    m /= np.linalg.norm(m, axis=1, keepdims=True)
    # a frame (a, b, m) per face: a is the camera's x axis made perpendicular to m
    rot, _ = device.pose()
    a = rot[0] - (m @ rot[0])[:, None] * m
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    b = np.cross(m, a)
    on_plane = rays / np.sum(rays * m[:, None, :], axis=2, keepdims=True)  # unit distance
    q = np.stack([np.sum(on_plane * a[:, None], 2), np.sum(on_plane * b[:, None], 2)], -1)
    d = q[:, 1] - q[:, 0]
    sep = np.linalg.norm(d, axis=1)
    along = d / sep[:, None]
    roll = np.arctan2(along[:, 1], along[:, 0])
    if lm.shape[1] >= 3:
        r = np.sum((q[:, 2] - 0.5 * (q[:, 0] + q[:, 1])) * along, axis=1) / sep
        yaw = np.clip(np.arctan2(r, nose_depth), -MAX_YAW, MAX_YAW)
    else:
        yaw = np.zeros(n)
    if lm.shape[1] >= 5:
        across = np.stack([-along[:, 1], along[:, 0]], axis=1)
        mouth = 0.5 * (q[:, 3] + q[:, 4]) - 0.5 * (q[:, 0] + q[:, 1])
        height = np.abs(np.sum(mouth * across, axis=1))
    else:
        height = np.full(n, np.nan)
    rng = ipd * np.cos(yaw) / sep
    eyes = origin + m * rng[:, None]
    return HeadPose(
        eyes, rng, yaw, roll, sep, height, m, origin, np.stack(nod(origin, eyes, look)), ipd
    )


def nod(
    origin: np.ndarray, eyes: np.ndarray, look: tuple[float, float, float] = LOOK
) -> tuple[np.ndarray, np.ndarray]:
    """How a camera at ``origin`` (3,) sees an upright head at ``eyes`` (N, 3) facing ``look``
    (metres): the face's downward direction (across its view) makes an angle a with the
    camera's image plane. Returns (cos a, sin a), each (N,): cos a = 1 when the head faces
    the camera; sin a > 0 when the mouth is nearer the camera than the eyes (the camera
    below the head's line of sight)."""
    e = np.asarray(eyes, np.float64).reshape(-1, 3)
    face = np.asarray(look, np.float64) - e
    face /= np.linalg.norm(face, axis=1, keepdims=True)
    down = np.array([0.0, -1.0, 0.0]) + face[:, 1:2] * face  # the face's down, across its view
    down /= np.maximum(np.linalg.norm(down, axis=1, keepdims=True), 1e-12)
    sight = np.asarray(origin, np.float64) - e
    sight /= np.linalg.norm(sight, axis=1, keepdims=True)
    sin_a = np.sum(down * sight, axis=1)
    return np.sqrt(np.clip(1.0 - sin_a**2, 1e-6, 1.0)), sin_a


def face_height(pose: HeadPose) -> np.ndarray:
    """(N,) metres: each face's eye-to-mouth length H from its IPD range R and its normalised
    ``height`` h, for a viewer facing the pose's ``look``: the mouth, H cos a across the line
    of sight and H sin a nearer than the eyes (``pose.nod``), is seen at
    h = H cos a / (R - H sin a), so H = h R / (cos a + h sin a). Meaningful where the read
    yaw is small (:data:`FRONTAL`)."""
    cos_a, sin_a = pose.nod
    return pose.height * pose.range / (cos_a + pose.height * sin_a)


def turn_bounds(
    yaw: np.ndarray, lag: float = NOSE_LAG, lead: float = NOSE_LEAD
) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi), each like ``yaw``: the true range over the IPD's for a face whose nose read
    a turn of ``yaw`` radians, if the nose's offset is ``lag`` (< 1: a turn read short, the
    true range nearer) to ``lead`` times the true one: cos(atan(tan|yaw| / k)) / cos(yaw).
    Both 1 at yaw 0; at a read 30 degrees, 0.94 and 1.05."""
    t = np.tan(np.abs(np.asarray(yaw, np.float64)))
    c = np.sqrt(1.0 + t * t)  # 1 / cos(yaw)
    return c / np.sqrt(1.0 + (t / lag) ** 2), c / np.sqrt(1.0 + (t / lead) ** 2)


def truncated_mean(mean: np.ndarray, sd: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The mean of a Gaussian (``mean``, ``sd`` > 0) truncated to [``lo``, ``hi``]
    (elementwise); the nearer bound where the Gaussian has no weight there to float
    precision."""
    a, b = (lo - mean) / sd, (hi - mean) / sd
    weight = ndtr(b) - ndtr(a)
    pdf = (np.exp(-0.5 * a * a) - np.exp(-0.5 * b * b)) / np.sqrt(2.0 * np.pi)
    inside = mean + sd * pdf / np.maximum(weight, 1e-300)
    return np.clip(np.where(weight > 1e-12, inside, np.where(mean < lo, lo, hi)), lo, hi)


def ranged_eyes(
    pose: HeadPose, height_m: float, spread: float = HEIGHT_SPREAD
) -> tuple[np.ndarray, np.ndarray]:
    """The faces ranged with one viewer's face height, ``height_m`` metres (measured by
    :func:`face_height`), and their IPD.

    The range is the mean of the face height's range, a Gaussian of relative sd ``spread``,
    within what the IPD allows for the read turn (:func:`turn_bounds` times the IPD's range;
    a truncated Gaussian): a frontal face keeps its IPD's range, a turned one is ranged by its
    height where that lies within the interval, by the nearer end where it does not. The
    IPD's range where the mouth was not seen.

    Returns:
        The eyes (N, 3) metres, and (N,) how much nearer the height ranged each face than the
        IPD did (a share; NaN where the mouth was not seen).
    """
    h = pose.height
    ok = np.isfinite(h) & (h > 0)
    rng = pose.range.copy()
    nearer = np.full(len(rng), np.nan)
    cos_a, sin_a = pose.nod[:, ok]
    by_height = height_m * (cos_a / h[ok] + sin_a)  # face_height solved for the range
    nearer[ok] = 1.0 - by_height / rng[ok]
    lo, hi = turn_bounds(pose.yaw[ok])
    rng[ok] = truncated_mean(by_height, spread * by_height, lo * rng[ok], hi * rng[ok])
    return pose.origin + pose.rays * rng[:, None], nearer


def prior_ranged_eyes(pose: HeadPose) -> np.ndarray:
    """(N, 3) metres: the faces ranged as :func:`ranged_eyes` does with the typical adult face
    height (:data:`FACE_HEIGHT` x ``pose.ipd``) and its wider spread (:data:`PRIOR_SPREAD`):
    a viewer whose own height is not measured yet."""
    return ranged_eyes(pose, FACE_HEIGHT * pose.ipd, PRIOR_SPREAD)[0]


def landmarks_of_head(
    device: Device,
    eyes: np.ndarray,
    yaw: np.ndarray | float = 0.0,
    ipd: float = IPD,
    nose_depth: float = NOSE_DEPTH,
    look: tuple[float, float, float] | None = None,
    mouth: float | None = None,
) -> np.ndarray:
    """The inverse of :func:`head_pose` (tests): where the eyes and the nose tip of heads with
    their eyes' midpoint at ``eyes`` (N, 3) metres appear, each head facing ``look`` (None:
    the camera's centre), upright, turned by ``yaw`` radians (N,) about its vertical;
    (N, 3, 2) pixels, or (N, 5, 2) with the mouth corners (0.7 IPD apart, ``mouth`` metres
    below the eyes across the face, in the eyes' plane)."""
    e = np.asarray(eyes, np.float64).reshape(-1, 3)
    yw = np.broadcast_to(np.asarray(yaw, np.float64), (len(e),))
    out = np.empty((len(e), 3 if mouth is None else 5, 2))
    for i, (p, t) in enumerate(zip(e, yw, strict=True)):
        target = np.asarray(device.position if look is None else look, np.float64)
        back = target - p  # where the head faces
        back /= np.linalg.norm(back)
        side = np.cross(np.array([0.0, 1.0, 0.0]), back)
        side /= np.linalg.norm(side)
        up = np.cross(back, side)
        c, s = np.cos(t), -np.sin(t)  # positive: the nose toward the image's right
        side_t, back_t = c * side + s * back, c * back - s * side
        pts = [
            p - 0.5 * ipd * side_t,
            p + 0.5 * ipd * side_t,
            p + nose_depth * ipd * back_t - 0.5 * ipd * up,
        ]
        if mouth is not None:
            pts += [p - 0.35 * ipd * side_t - mouth * up, p + 0.35 * ipd * side_t - mouth * up]
        out[i] = device.project(np.stack(pts))
    return out
