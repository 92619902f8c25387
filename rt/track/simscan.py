"""A person scanned in 3-D, placed in the tracking camera by the eyes: a textured mesh.

A photograph drawn at a turn it was not taken at keeps the nose's look as photographed
(:mod:`viewcomp.rt.track.simscene`); a head scanned in 3-D does not: its surface is measured,
its texture photographed on it, so a turned head shows its own nose, cheek and ear as a camera
would see them. A :class:`Scan` is such a mesh (vertices, triangles, texture coordinates and
the texture), annotated in 3-D (the eye contours' centres, the mouth corners, the nose tip).

The head's frame follows from the annotation: ``lat`` along the eye line, ``up`` from the
mouth corners' midpoint to the eyes' midpoint (made perpendicular to ``lat``), ``fwd`` out of
the face (toward the nose); the eyes' midpoint is the origin and the eyes are drawn ``ipd``
metres apart. Posed as :func:`viewcomp.rt.track.simscene.render_person` poses a photograph
(its eyes' midpoint at a known 3-D point, facing the camera or a point of the screen, turned
about its vertical), it is drawn texel by texel: each texel of the texture (of a level of its
Gaussian pyramid, fine enough that texels land at most half a frame pixel apart) becomes the
surface point its triangle maps it to, and the points facing the camera are splatted far to
near (:func:`viewcomp.rt.track.simscene.splat`: the nearest surface wins, holes filled in).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from viewcomp.calib.world.rig import Device
from viewcomp.rt.track.anatomy import IPD
from viewcomp.rt.track.simscene import head_axes, splat

MAX_BYTES = 256 << 20  # a mesh file larger than this is refused before it is read
# Texels land at most this far apart in the frame (pixels): the splat leaves no holes
TEXEL_SPACING = 0.5
PYRAMID = 5  # texture levels: the coarsest serves a head about 16 times smaller


@dataclass
class Scan:
    """A textured head mesh, annotated.

    ``vertices`` (V, 3) in the head's frame (lat, up, fwd), in units of the eyes' separation
    (the eyes at (-0.5, 0, 0) and (0.5, 0, 0)); ``faces`` (F, 3) vertex indices and ``uv``
    (F, 3, 2) each corner's texture pixel (x right, y down, pixel centres at integers) of
    ``texture`` (h, w, 3) uint8 BGR; ``nose`` (3,) the nose tip in the same frame. Counter-
    clockwise triangles (seen from outside) face out.
    """

    name: str
    vertices: np.ndarray
    faces: np.ndarray
    uv: np.ndarray
    texture: np.ndarray
    nose: np.ndarray
    _levels: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = field(
        default_factory=dict, repr=False, compare=False
    )

    @staticmethod
    def annotated(
        name: str,
        vertices: np.ndarray,
        faces: np.ndarray,
        uv: np.ndarray,
        texture: np.ndarray,
        eyes: np.ndarray,
        mouth: np.ndarray,
        nose: np.ndarray,
    ) -> Scan:
        """A scan in its own units (``vertices`` (V, 3), any length unit) with ``eyes``
        (2, 3) the eye centres, ``mouth`` (2, 3) the mouth corners, ``nose`` (3,) the nose tip
        (same units), put in the head's frame (see the module's docstring); ``uv`` (F, 3, 2)
        each triangle corner's texture coordinates as a Wavefront OBJ file gives them (u
        right, v up, 0..1 across ``texture``). Triangles wound the other way are turned to
        face out (toward the nose's side)."""
        e, m = np.asarray(eyes, np.float64), np.asarray(mouth, np.float64)
        mid = e.mean(axis=0)
        sep = float(np.linalg.norm(e[1] - e[0]))
        lat = (e[1] - e[0]) / sep
        up = mid - m.mean(axis=0)
        up -= (up @ lat) * lat
        up /= np.linalg.norm(up)
        fwd = np.cross(lat, up)
        tip = np.asarray(nose, np.float64) - mid
        if tip @ fwd < 0:  # the eyes were given right to left: lat points the other way
            lat, fwd = -lat, -fwd
        rot = np.stack([lat, up, fwd])
        v = (np.asarray(vertices, np.float64) - mid) @ rot.T / sep
        f = np.asarray(faces, np.int64)
        h, w = texture.shape[:2]
        t = np.asarray(uv, np.float64)
        px = np.stack([t[..., 0] * w - 0.5, (1.0 - t[..., 1]) * h - 0.5], axis=-1)
        normals = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
        if np.mean(normals[:, 2] > 0) < 0.5:  # most of a face scan faces forward
            f, px = f[:, ::-1], px[:, ::-1]
        return Scan(name, v, f, px, texture, rot @ tip / sep)

    def landmarks(
        self, device: Device, eye: np.ndarray, turn: float = 0.0, look: np.ndarray | None = None,
        ipd: float = IPD,
    ) -> np.ndarray:  # fmt: skip
        """(3, 3) metres, world frame: the eye on the image's left when the head faces the
        camera, the other eye, the nose tip, as :func:`render_scan` draws them."""
        pts = np.array([[-0.5, 0.0, 0.0], [0.5, 0.0, 0.0], self.nose]) * ipd
        return np.asarray(eye, np.float64) + pts @ head_axes(device, eye, turn, look).T

    def texels(self, level: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The texels of pyramid ``level`` that a triangle covers: their surface points
        (M, 3) (head frame, eye separations), their triangles' outward normals (M, 3) and
        their colours (M, 3) float32 BGR 0..1. Computed once per level."""
        if level not in self._levels:
            self._levels[level] = _texels(self, level)
        return self._levels[level]

    def spacing(self) -> float:
        """The mean distance between neighbouring texels of level 0 on the surface, in eye
        separations: the square root of the surface's area over its texels'."""
        v, f, uv = self.vertices, self.faces, self.uv
        cross = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
        area = 0.5 * np.linalg.norm(cross, axis=1)
        a, b = uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
        texels = 0.5 * np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
        return float(np.sqrt(area.sum() / max(texels.sum(), 1e-12)))

    def posed(self, yaw: float) -> tuple[Scan, float]:
        """The scan and the turn that draw it with a total yaw of ``yaw`` radians (a scan
        is measured all round the face: drawn turned either way as it is)."""
        return self, yaw

    def render(
        self, frame: np.ndarray, device: Device, eye: np.ndarray, turn: float = 0.0,
        gain: float = 1.0, occluder: tuple[float, float, float, float] | None = None,
        look: np.ndarray | None = None,
    ) -> np.ndarray:  # fmt: skip
        """:func:`render_scan` of this scan (63 mm between the eyes)."""
        return render_scan(frame, device, self, eye, turn, IPD, gain, occluder, look)


def render_scan(
    frame: np.ndarray,
    device: Device,
    scan: Scan,
    eye: np.ndarray,
    turn: float = 0.0,
    ipd: float = IPD,
    gain: float = 1.0,
    occluder: tuple[float, float, float, float] | None = None,
    look: np.ndarray | None = None,
) -> np.ndarray:
    """``frame`` (h, w, 3) float32 BGR 0..1 with ``scan``'s head drawn over it (a new array).

    The arguments are :func:`viewcomp.rt.track.simscene.render_person`'s: ``eye`` (3,)
    metres, the eyes' midpoint; ``turn`` radians about the head's vertical (positive: the
    nose toward the image's right); ``gain`` the light; ``occluder`` (x0, y0, x1, y1) a
    rectangle over the face in eye separations from the eyes' midpoint, x toward the
    image's right and y down as the head faces the camera, drawn dark grey on the face;
    ``look`` the point the head faces before its turn (None: the camera's centre).
    """
    e = np.asarray(eye, np.float64)
    rng = float(np.linalg.norm(e - np.asarray(device.position, np.float64)))
    step = device.focal() * scan.spacing() * ipd / rng  # level 0's texels, frame pixels apart
    level = int(np.clip(np.floor(np.log2(TEXEL_SPACING / step)), 0, PYRAMID - 1)) if step else 0
    pts, normals, colour = scan.texels(level)
    colour = colour * np.float32(gain)
    if occluder is not None:
        x0, y0, x1, y1 = occluder
        inside = (pts[:, 0] >= x0) & (pts[:, 0] <= x1) & (-pts[:, 1] >= y0) & (-pts[:, 1] <= y1)
        colour[inside] = 0.18
    rot = head_axes(device, e, turn, look)
    world = e + (pts * ipd) @ rot.T
    facing = np.sum((normals @ rot.T) * (np.asarray(device.position) - world), axis=1) > 0
    sight = np.asarray(device.position, np.float64) - e
    sight /= np.linalg.norm(sight)
    depth = (world - np.asarray(device.position)) @ (-sight)
    rgba = np.concatenate([colour, facing[:, None].astype(np.float32)], axis=1)
    return splat(frame, device.project(world), depth, rgba, np.ones(len(world), bool))


def _texels(scan: Scan, level: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:meth:`Scan.texels`: each texel centre of the pyramid level inside a triangle (in
    texture space) mapped to the surface by its barycentric coordinates."""
    tex = scan.texture
    for _ in range(level):
        tex = cv2.pyrDown(tex)
    h, w = tex.shape[:2]
    uv = scan.uv / 2.0**level  # (F, 3, 2): pyrDown centres its pixel j on the finer one's 2 j
    owner = np.full((h, w), -1, np.int32)
    corners = np.rint(uv * 16.0).astype(np.int32)  # 4 bits of sub-pixel precision
    for i, tri in enumerate(corners):
        cv2.fillConvexPoly(owner, tri, i, lineType=cv2.LINE_8, shift=4)
    yy, xx = np.nonzero(owner >= 0)
    tri = owner[yy, xx]
    a, b, c = uv[tri, 0], uv[tri, 1], uv[tri, 2]
    p = np.stack([xx, yy], axis=1).astype(np.float64)
    d1, d2, dp = b - a, c - a, p - a
    den = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
    den = np.where(np.abs(den) > 1e-12, den, 1e-12)
    l1 = np.clip((dp[:, 0] * d2[:, 1] - d2[:, 0] * dp[:, 1]) / den, 0.0, 1.0)
    l2 = np.clip((d1[:, 0] * dp[:, 1] - dp[:, 0] * d1[:, 1]) / den, 0.0, 1.0 - l1)
    v, f = scan.vertices, scan.faces
    p0, p1, p2 = v[f[tri, 0]], v[f[tri, 1]], v[f[tri, 2]]
    pts = p0 + l1[:, None] * (p1 - p0) + l2[:, None] * (p2 - p0)
    n = np.cross(p1 - p0, p2 - p0)
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
    return pts, n, tex[yy, xx].astype(np.float32) / 255.0


def read_obj(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A Wavefront OBJ mesh with texture coordinates: vertices (V, 3), faces (F, 3) vertex
    indices and (F, 3, 2) texture coordinates (u right, v up, 0..1). Triangles only.

    Raises:
        ValueError: naming the file (and line): larger than :data:`MAX_BYTES`, not
            triangles, indices out of range, no texture coordinates.
    """
    size = Path(path).stat().st_size
    if size > MAX_BYTES:
        raise ValueError(f"{path}: {size} bytes, more than a head mesh's {MAX_BYTES}")
    verts: list[list[float]] = []
    coords: list[list[float]] = []
    faces: list[list[int]] = []
    tex: list[list[int]] = []
    with open(path, encoding="utf-8") as fh:
        for n, line in enumerate(fh, 1):
            word, _, rest = line.partition(" ")
            try:
                if word == "v":
                    verts.append([float(x) for x in rest.split()[:3]])
                elif word == "vt":
                    coords.append([float(x) for x in rest.split()[:2]])
                elif word == "f":
                    ends = [c.split("/") for c in rest.split()]
                    if len(ends) != 3 or any(len(c) < 2 or not c[1] for c in ends):
                        raise ValueError("a face that is not a triangle with texture coordinates")
                    faces.append([int(c[0]) - 1 for c in ends])
                    tex.append([int(c[1]) - 1 for c in ends])
            except ValueError as err:
                raise ValueError(f"{path}:{n}: {err}") from None
    v, t = np.asarray(verts, np.float64), np.asarray(coords, np.float64)
    f, ft = np.asarray(faces, np.int64), np.asarray(tex, np.int64)
    if len(f) == 0 or v.shape[1:] != (3,) or t.shape[1:] != (2,):
        raise ValueError(f"{path}: no textured triangles")
    if f.min() < 0 or f.max() >= len(v) or ft.min() < 0 or ft.max() >= len(t):
        raise ValueError(f"{path}: a face refers to a vertex or texture coordinate not given")
    return v, f, t[ft]
