"""What reaches an emulated camera's pixels: the simulator's scene on a supersampled grid.

The physics is the simulator's (:class:`~viewcomp.calib.sim.simcamera.SimCamera` renders it):
on a grid ``supersample`` times finer than the camera's, per sample s,

    R(s) = reflectance toward the camera * fall-off * vignette   (per camera channel, (3,))
    A(s) = the room light's radiance * vignette                  ((3,))

are rendered once per screen by a SimCamera whose projector is linear with identity
primaries (R = radiance(full white) - radiance(black), A = radiance(black)). The projector's
pixels are boxes: sample s shows the pattern's levels of the projector pixel it falls in
(nearest, not interpolated). A camera exposure then integrates

    integral(s) = R(s) * (mixing @ E_rgb(s) + E_w(s) * mixing @ 1) + A(s) * exposure

(E_w looked up by min(R, G, B), only when the sequence has a white segment)

with E the drive integrals of :meth:`~viewcomp.calib.emu.dlp.DlpModel.drive_luts` looked
up per sample from its level (and its row's window: a rolling shutter), and each camera
pixel is the mean of its f x f samples (pixels integrate area).
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import replace
from functools import cached_property

import cv2
import numpy as np

from viewcomp.calib.sim.simcamera import SimCamera
from viewcomp.calib.sim.simulator import AnyScreen, CameraPhysics, ProjectorPhysics, Simulator
from viewcomp.calib.world.rig import Rig

#: Level maps (per shown pattern) a scene keeps.
CODE_CACHE = 6


def supersampled_rig(rig: Rig, factor: int) -> Rig:
    """The rig with a camera of ``factor`` times the resolution over the same field of view
    (principal point at the centre: the rig's must be None)."""
    cam = rig.camera
    if cam.principal_point is not None:
        raise ValueError("the emulated camera needs its principal point at the image centre")
    w, h = cam.resolution
    return replace(rig, camera=replace(cam, resolution=(w * factor, h * factor)))


class SceneView:
    """The scene as one camera pose sees it (see the module doc).

    ``rig``: the true rig (camera resolution = the emulated camera's); ``factor``: samples
    per camera pixel along each axis; ``mixing`` (3, 3): camera channel i per unit of
    projector primary j; ``ambient`` (3,): the room light; ``vignetting``: exponent on cos^4.
    """

    def __init__(
        self,
        rig: Rig,
        factor: int,
        mixing: np.ndarray,
        ambient: tuple[float, float, float],
        vignetting: float = 1.0,
    ) -> None:
        if factor < 1:
            raise ValueError(f"supersample factor must be >= 1, got {factor}")
        self.rig = rig
        self.factor = int(factor)
        self.mixing = np.asarray(mixing, np.float32)
        self.white = self.mixing.sum(axis=1)  # camera channels of a white segment
        linear = ProjectorPhysics(
            gamma=(1.0, 1.0, 1.0),
            leak=0.0,
            primaries=((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)),
        )
        sim = Simulator(
            rig=supersampled_rig(rig, self.factor),
            projector=linear,
            camera=CameraPhysics(vignetting=False),
            ambient=ambient,
        )
        self._cam = SimCamera(sim, blur_px=0.0)
        self._vign = self._cam.view.vignette.astype(np.float32) ** np.float32(vignetting)
        self._screens: dict[int, tuple[AnyScreen, np.ndarray, np.ndarray]] = {}
        self._codes: OrderedDict[int, np.ndarray] = OrderedDict()

    @property
    def shape(self) -> tuple[int, int]:
        """(Hc, Wc) of the camera image."""
        w, h = self.rig.camera.resolution
        return (h, w)

    @cached_property
    def _flat_index(self) -> np.ndarray:
        """(Hs, Ws) int64: the projector pixel (flat index v W + u) each sample falls in."""
        view = self._cam.view
        w, h = self.rig.projector.resolution
        u = np.clip(np.rint(view.map_u), 0, w - 1).astype(np.int64)
        v = np.clip(np.rint(view.map_v), 0, h - 1).astype(np.int64)
        return v * w + u

    def terms(self, screen: AnyScreen) -> tuple[np.ndarray, np.ndarray]:
        """(R, A) of ``screen``: (Hs, Ws, 3) float32 each (see the module doc), kept."""
        got = self._screens.get(id(screen))
        if got is None or got[0] is not screen:
            w, h = self.rig.projector.resolution
            black = self._cam.radiance(screen, np.zeros((h, w, 3), np.uint8))
            full = self._cam.radiance(screen, np.full((h, w, 3), 255, np.uint8))
            v = self._vign[..., None]
            got = (screen, (full - black) * v, black * v)
            self._screens[id(screen)] = got
        return got[1], got[2]

    def levels(self, key: int, image: np.ndarray) -> np.ndarray:
        """(Hs, Ws, 3) uint8: the levels R, G, B of the projector pixel under each sample, for
        the pattern ``image`` (H, W, 3) uint8 known as ``key`` (kept)."""
        got = self._codes.get(key)
        if got is None:
            got = np.asarray(image, np.uint8).reshape(-1, 3)[self._flat_index]
            self._codes[key] = got
            while len(self._codes) > CODE_CACHE:
                self._codes.popitem(last=False)
        else:
            self._codes.move_to_end(key)
        return got

    def integrate(
        self,
        screen: AnyScreen,
        pieces: list[tuple[int, np.ndarray, np.ndarray]],
        exposure: float,
    ) -> np.ndarray:
        """The exposure's integral per camera pixel: (Hc, Wc, 3) float32 (radiance x seconds).

        ``pieces``: per pattern on screen during the exposure, (key, image (H, W, 3) uint8,
        luts (N, 4, 256)) with N = 1 (every row the same window) or N = Hc (one window per
        camera row); ``exposure``: the seconds every row integrates the room light.
        """
        r_term, a_term = self.terms(screen)
        hs, ws = r_term.shape[:2]
        f = self.factor
        drive = np.zeros((hs, ws, 3), np.float32)
        white = None  # the white segment's drive, only when it lights anything
        for key, image, luts in pieces:
            lv = self.levels(key, image)
            n = luts.shape[0]
            lut32 = luts.astype(np.float32)
            has_white = bool(np.any(lut32[:, 3]))
            if has_white and white is None:
                white = np.zeros((hs, ws), np.float32)
            if n == 1:  # one window: a table lookup per channel
                drive += cv2.LUT(lv, np.ascontiguousarray(lut32[0, :3].T[None]))
                if has_white:
                    white += lut32[0, 3][lv.min(axis=-1)]
            else:  # a window per camera row: sample row // f picks its row's table
                flat = lut32.transpose(1, 0, 2).reshape(4, n * 256)
                base = (np.arange(hs) // f * 256)[:, None]
                for c in range(3):
                    drive[..., c] += flat[c][base + lv[..., c]]
                if has_white:
                    white += flat[3][base + lv.min(axis=-1)]
        # camera channel i = sum_j mixing[i, j] d_j
        light = np.asarray(cv2.transform(drive, self.mixing), np.float32)
        if white is not None:
            light += white[..., None] * self.white
        total = r_term * light
        total += a_term * np.float32(exposure)
        hc, wc = self.shape
        # INTER_AREA with an integer factor is the exact mean of each f x f block
        return cv2.resize(total, (wc, hc), interpolation=cv2.INTER_AREA)
