"""The surface a photograph is painted on when the simulator draws it as a head (2.5-D).

A relief says how far the head's surface stands in front of its eyes at each point of the
face: ``forward(lat, up, tip, ipd)`` metres, at ``lat`` metres across the face from the eyes'
midpoint (toward the eye on the image's right) and ``up`` metres up, for a photograph whose
nose tip lies at ``tip`` (lateral, up) metres. Two kinds:

- :class:`Ridge`: a model, a vertical cylinder of ``HEAD_RADIUS`` IPD through the eyes and a
  nose ridge ``RIDGE`` IPD high at the tip (0.56 IPD in front of the pupils with the
  cylinder's bulge: MediaPipe's canonical face model puts it 0.57-0.59). Nothing but the nose
  stands out: eye sockets, cheeks, lips and chin are the cylinder's.
- :class:`MeasuredRelief`: a scanned face's surface (a depth map made of its points by
  :meth:`MeasuredRelief.of_surface`), stretched down and sheared sideways so its nose tip
  lies under the photograph's: the nose's wings and bridge, the eye sockets, the cheeks and
  the lips stand where a real face has them (the astronaut's photograph drawn turned 25 and
  45 degrees on it: YuNet reads her painted nose moving a median 0.70 and 0.73 as far as the
  drawn tip, within what real photographs show; on the ridge 0.55 and 0.46, measured the same
  way).

Neither is the tracker's nose model (``anatomy.NOSE_DEPTH``, which allows for how far out a
detector puts a nose).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
from scipy.ndimage import distance_transform_edt, gaussian_filter, map_coordinates

# The nose ridge's height at the tip (IPDs): with the roundness between the eyes, the tip 0.56
# IPD in front of the pupils. The simulator's own, not the tracker's anatomy.NOSE_DEPTH.
RIDGE = 0.5
HEAD_RADIUS = 1.3  # the head's roundness: a cylinder of this radius, in IPDs (82 mm)


class Relief(Protocol):
    """A surface a photograph can be painted on (:class:`Ridge`, :class:`MeasuredRelief`)."""

    def forward(
        self, lat: np.ndarray, y: np.ndarray, tip: tuple[float, float], ipd: float
    ) -> np.ndarray:
        """How far (metres) the surface stands in front of the eyes at ``lat`` metres across
        the face and ``y`` metres up, for a photograph whose nose tip is at ``tip``."""
        ...

    def mirrored(self) -> Relief:
        """The relief of the mirrored face."""
        ...


def cylinder(lat: np.ndarray, ipd: float = 1.0) -> np.ndarray:
    """How far (same units as ``ipd``) the head's cylinder of ``HEAD_RADIUS`` IPD stands in
    front of the eyes at ``lat`` across the face (0 at the eyes, +-``ipd`` / 2)."""
    r = HEAD_RADIUS * ipd
    u = np.clip(np.abs(lat) / r, 0.0, 0.999)
    return r * (np.sqrt(1.0 - u**2) - np.sqrt(1.0 - (0.5 * ipd / r) ** 2))


@dataclass(frozen=True)
class Ridge:
    """The model relief: a nose ridge ``height`` IPD high at the tip on a cylinder."""

    height: float = RIDGE

    def forward(
        self, lat: np.ndarray, y: np.ndarray, tip: tuple[float, float], ipd: float
    ) -> np.ndarray:
        """How far (metres) the surface stands forward of the eyes at ``lat`` metres across
        the face and ``y`` metres up: a ridge from between the eyes (35 % of the tip's
        height) to the nose tip at ``tip`` (lateral, up metres), on the cylinder (the far
        cheek recedes and the outline moves when the head turns)."""
        ln, yn = tip
        t = np.clip(y / yn, 0.0, 1.0) if yn < 0 else np.zeros_like(y)
        along = np.where(
            y > 0,
            0.35 * np.exp(-0.5 * (y / (0.12 * ipd)) ** 2),
            np.where(y >= yn, 0.35 + 0.65 * t, np.exp(-0.5 * ((y - yn) / (0.12 * ipd)) ** 2)),
        )
        ridge = self.height * ipd * along * np.exp(-0.5 * ((lat - t * ln) / (0.28 * ipd)) ** 2)
        at_eyes = self.height * ipd * 0.35 * np.exp(-0.5 * (0.5 / 0.28) ** 2)  # the ridge's
        return ridge + cylinder(lat, ipd) - at_eyes

    def mirrored(self) -> Ridge:
        """The relief of the mirrored face (the ridge follows the tip: the same)."""
        return self


MODEL = Ridge()  # the model relief, with the simulator's RIDGE

# A measured relief's grid: lateral +-LAT_SPAN, up from UP_SPAN[0] to UP_SPAN[1] (IPDs) in
# steps of GRID; outside what the scan covers it blends into the cylinder over BLEND steps
GRID = 0.01
LAT_SPAN = 1.45
UP_SPAN = (-2.6, 1.9)
BLEND = 5.0


@dataclass(frozen=True, eq=False)  # an array inside: compared by identity
class MeasuredRelief:
    """A scanned face's relief: ``depth`` (rows, cols) IPDs in front of the eyes on the grid
    lateral -LAT_SPAN.. (columns), up UP_SPAN[0].. (rows), ``GRID`` IPD apart (cell centres
    at half steps); ``tip`` (lateral, up) IPDs, the scan's nose tip."""

    depth: np.ndarray
    tip: tuple[float, float]

    @staticmethod
    def of_surface(points: np.ndarray, tip: np.ndarray) -> MeasuredRelief:
        """The relief of a face's surface ``points`` (M, 3): (lat, up, fwd) in IPDs, the eyes
        at (+-0.5, 0, 0), dense enough that most grid cells hold one (a scan's texels,
        :meth:`viewcomp.rt.track.simscan.Scan.texels`); ``tip`` (3,) its nose tip. Each cell
        takes its most forward point; empty cells the nearest filled one's; the map is
        smoothed over a cell, blends into the cylinder where the scan ends and is levelled
        so the eyes lie at depth 0."""
        p = np.asarray(points, np.float64)
        cols = round(2 * LAT_SPAN / GRID)
        rows = round((UP_SPAN[1] - UP_SPAN[0]) / GRID)
        depth = np.full((rows, cols), -np.inf)
        c = np.floor((p[:, 0] + LAT_SPAN) / GRID).astype(np.int64)
        r = np.floor((p[:, 1] - UP_SPAN[0]) / GRID).astype(np.int64)
        ok = (c >= 0) & (c < cols) & (r >= 0) & (r < rows)
        if not ok.any():
            raise ValueError("the surface has no points on the face's grid")
        np.maximum.at(depth, (r[ok], c[ok]), p[ok, 2])
        known = np.isfinite(depth)
        nearest = distance_transform_edt(~known, return_distances=False, return_indices=True)
        depth = gaussian_filter(depth[tuple(nearest)], 1.0)
        lat = (np.arange(cols) + 0.5) * GRID - LAT_SPAN
        weight = gaussian_filter(known.astype(np.float64), BLEND)
        depth = weight * depth + (1.0 - weight) * cylinder(lat)[None, :]
        made = MeasuredRelief(depth, (float(tip[0]), float(tip[1])))
        # the eyes on the surface at depth 0 exactly, as the photographs' pupils are placed:
        # less the plane through the map's depth at the two eyes
        at = made.forward(np.array([-0.5, 0.5]), np.zeros(2), made.tip, 1.0)
        plane = 0.5 * (at[0] + at[1]) + (at[1] - at[0]) * lat
        return MeasuredRelief(depth - plane[None, :], made.tip)

    def forward(
        self, lat: np.ndarray, y: np.ndarray, tip: tuple[float, float], ipd: float
    ) -> np.ndarray:
        """How far (metres) the surface stands forward of the eyes at ``lat`` metres across
        the face and ``y`` metres up, for a photograph whose nose tip is at ``tip`` (lateral,
        up metres): below the eyes the scan is stretched vertically so its tip is as far
        below them as the photograph's and sheared sideways (in proportion to the height
        below the eyes, all of it from the tip down) so its tip lies under the photograph's;
        above the eyes it is the scan's."""
        lat = np.asarray(lat, np.float64) / ipd
        y = np.asarray(y, np.float64) / ipd
        ln, yn = tip[0] / ipd, tip[1] / ipd
        if yn < 0:
            ys = np.where(y < 0, y * (self.tip[1] / yn), y)
            shift = np.clip(y / yn, 0.0, 1.0) * (ln - self.tip[0])
        else:
            ys, shift = y, np.zeros_like(y)
        lat, ys, shift = np.broadcast_arrays(lat, ys, shift)
        col = (lat - shift + LAT_SPAN) / GRID - 0.5
        row = (ys - UP_SPAN[0]) / GRID - 0.5
        out = map_coordinates(self.depth, [row.ravel(), col.ravel()], order=1, mode="nearest")
        return out.reshape(lat.shape) * ipd

    def mirrored(self) -> MeasuredRelief:
        """The relief of the mirrored face: lateral reversed (the grid is symmetric)."""
        return MeasuredRelief(self.depth[:, ::-1].copy(), (-self.tip[0], self.tip[1]))
