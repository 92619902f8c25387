"""The runtime model: what calibration hands to run time, for one method, as float32 arrays.

It is the contract between ``viewcomp.calib`` (the fits build it) and the per-frame code (the
numpy reference in :mod:`~viewcomp.calib.model.reference`, the GL compensator and the mpv
export read it). Conventions: per-pixel arrays are (H, W, ...) on the projector grid, row 0 at
the top; values are linear light in the calibration camera's units (0..1 = full scale).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np

from viewcomp.calib.model.lobe import lobe_lookup, lobe_position

Method = Literal["pixel", "paper", "identity"]


@dataclass
class RuntimeModel:
    """What the per-frame formula needs, for one method, as float32 arrays.

    Common: ``refl`` (H, W, 3) unit reflection vectors R(x); ``pos`` (H, W, 3) surface points
    in metres; ``cam_eye`` (3,) the calibration camera's position; ``fwd_lut`` (256, 3) level
    -> linear value; ``inv_lut`` (N, 3) linear value -> level/255, sampled uniformly on
    [``inv_lo``, ``inv_hi``] per channel.

    ``pixel``: ``Ww``/``Wc`` (H, W, 3, 3), ``Aw``/``Ac`` (H, W, 3), the specular lobe
    ``lobe`` (n, 3) over the coordinate of :mod:`~viewcomp.calib.model.lobe` (``lobe_half``:
    the half-vector angle, else the mirror angle), ``lobe_black`` (3,) the share of the white
    screen's black level Aw that the lobe reflects (projector leak), and derived from those,
    :attr:`cam_lobe`.
    ``paper``: ``Ww`` (3, 3) = W~_w, ``Wc_inv`` (3, 3) = (W~_c at the eye)^-1; ``Aw``/``Ac``
    are unused (zeros); ``fwd_lut`` is rho_w and ``inv_lut`` is rho_c^-1 at the current eye.
    """

    method: Method
    refl: np.ndarray
    pos: np.ndarray
    cam_eye: np.ndarray
    fwd_lut: np.ndarray
    inv_lut: np.ndarray
    inv_lo: np.ndarray
    inv_hi: np.ndarray
    Ww: np.ndarray
    Wc: np.ndarray | None = None
    Wc_inv: np.ndarray | None = None
    Aw: np.ndarray | None = None
    Ac: np.ndarray | None = None
    lobe: np.ndarray = field(default_factory=lambda: np.zeros((2, 3), np.float32))
    lobe_half: bool = True
    lobe_black: np.ndarray = field(default_factory=lambda: np.zeros(3, np.float32))

    @functools.cached_property
    def cam_lobe(self) -> np.ndarray:
        """The lobe seen from the calibration camera, per channel: (H, W, 3) float32, >= 0
        (pixel method; every backend reads this one).

        Computed on first use from ``refl``, ``pos``, ``cam_eye``, ``lobe`` and ``lobe_half``
        and kept (``dataclasses.replace`` makes a new model, which computes its own);
        assigning to those fields of an existing model afterwards does not update it.
        """
        t = lobe_position(self.refl, self.pos, self.cam_eye, self.lobe_half)
        return lobe_lookup(np.asarray(self.lobe, np.float32), t)

    @property
    def shape(self) -> tuple[int, int]:
        """(H, W) of the projector grid."""
        return int(self.refl.shape[0]), int(self.refl.shape[1])

    def subsample(self, step: int) -> RuntimeModel:
        """The same model on every ``step``-th pixel (for tone-map thumbnails)."""

        def sub(a: np.ndarray | None, per_pixel_ndim: int) -> np.ndarray | None:
            if a is None or a.ndim < per_pixel_ndim:
                return a
            return a[::step, ::step]

        return replace(
            self,
            refl=self.refl[::step, ::step],
            pos=self.pos[::step, ::step],
            Ww=self.Ww if self.Ww.ndim < 4 else self.Ww[::step, ::step],
            Wc=sub(self.Wc, 4),
            Aw=sub(self.Aw, 3),
            Ac=sub(self.Ac, 3),
        )
