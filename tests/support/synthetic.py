"""Synthetic, plausible runtime models and test frames for tests and benchmarks (no GL).

:class:`SyntheticCompensation` stands in for ``viewcomp.calib.comp.compensation.Compensation``
(the duck-typed ``comp`` of :func:`viewcomp.rt.render.pipeline.render_file`) on a synthetic model
of any size; :func:`make_compensation` gives a real one from a small simulated calibration
(``tests.support.calibrations.small_calibration``).

The geometry is a flat screen z = 0 lit by a projector at (0, -0.03, 0.5) looking at the
origin (vertical field of view 20 degrees); the calibration camera is at (0, 0.035, 0.5).
Colour mixing matrices are smooth random fields, diagonal-dominant; responses are gamma 2.2
curves; the specular lobe is kappa (R.V)^20 with kappa ~0.3, tabulated over the mirror angle.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from tests.support.calibrations import small_calibration
from viewcomp.calib.comp.compensation import Compensation
from viewcomp.calib.model.lobe import LOBE_N
from viewcomp.calib.model.runtime import Method, RuntimeModel
from viewcomp.calib.world.geometry import meet_screen
from viewcomp.rt.media.sample_clip import write_clip

PROJECTOR = np.array([0.0, -0.03, 0.5])
CAMERA = np.array([0.0, 0.035, 0.5])


def planar_geometry(
    width: int, height: int, fov_y_deg: float = 20.0
) -> tuple[np.ndarray, np.ndarray]:
    """(refl, pos) of a projector at PROJECTOR looking at the origin onto the plane z = 0.

    Returns float32 (H, W, 3) unit reflection vectors and surface points (metres); row 0 is
    the top of the projector image.
    """
    fwd = -PROJECTOR / np.linalg.norm(PROJECTOR)
    right = np.cross(fwd, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    f = 0.5 * height / np.tan(np.radians(fov_y_deg) / 2.0)
    u = (np.arange(width) + 0.5 - width / 2.0) / f
    v = (np.arange(height) + 0.5 - height / 2.0) / f
    d = fwd + u[None, :, None] * right - v[:, None, None] * up
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    pos = meet_screen(PROJECTOR, d, "projector")
    refl = d.copy()
    refl[..., 2] = -refl[..., 2]  # mirror about the normal (0, 0, 1)
    return refl.astype(np.float32), pos.astype(np.float32)


def _smooth_field(rng: np.random.Generator, h: int, w: int, n: int) -> np.ndarray:
    """n smooth random fields (H, W, n) in [-1, 1]: sums of a few low-frequency sinusoids."""
    yy = np.linspace(0.0, 1.0, h, dtype=np.float32)[:, None]
    xx = np.linspace(0.0, 1.0, w, dtype=np.float32)[None, :]
    out = np.empty((h, w, n), np.float32)
    for k in range(n):
        fx, fy, px, py = rng.uniform([0.5, 0.5, 0, 0], [2.0, 2.0, 2 * np.pi, 2 * np.pi])
        out[..., k] = 0.5 * np.sin(2 * np.pi * fx * xx + px) + 0.5 * np.sin(
            2 * np.pi * fy * yy + py
        )
    return out


def phong_table(kappa: np.ndarray, gamma: float) -> np.ndarray:
    """kappa (R.V)^gamma as a lobe table over the mirror angle: (LOBE_N, 3) float32, with
    R.V = 1 - t^2 at the table's coordinate t (viewcomp.calib.model.lobe)."""
    t = np.linspace(0.0, 1.0, LOBE_N)
    return (np.asarray(kappa)[None, :] * (1.0 - t * t)[:, None] ** gamma).astype(np.float32)


def synthetic_model(
    method: Method = "pixel",
    width: int = 160,
    height: int = 96,
    seed: int = 0,
    n_inv: int = 1024,
) -> RuntimeModel:
    """A random but well-conditioned RuntimeModel of any size for ``pixel`` or ``paper``.

    ``pixel``: per-pixel Ww (diagonal ~0.8, off-diagonal ~0.05), Wc = screen colour
    (0.9, 0.65, 0.45) times a similar field, ambients ~0.01..0.02, a lobe kappa (R.V)^20
    (kappa ~0.3) tabulated over the mirror angle,
    fwd_lut = l^2.2 (per channel exponents 2.1..2.3), inv_lut its inverse on [0, 1] (sampled
    uniformly in the square root, as docs/RUNTIME.md says).
    ``paper``: global Ww, Wc_inv, fwd_lut rho_w and inv_lut rho_c^-1 on [0, max rho_c].
    """
    rng = np.random.default_rng(seed)
    refl, pos = planar_geometry(width, height)
    levels = np.arange(256, dtype=np.float64) / 255.0
    gam = np.array([2.1, 2.2, 2.3])
    fwd = (levels[:, None] ** gam[None, :]).astype(np.float32)
    # Sample k at y = (k / (N - 1))^2 of the domain (uniform in the square root, RUNTIME.md).
    y = np.linspace(0.0, 1.0, n_inv)[:, None] ** 2
    inv = (y ** (1.0 / gam[None, :])).astype(np.float32)
    screen = np.array([0.9, 0.65, 0.45], np.float32)
    common = dict(
        refl=refl,
        pos=pos,
        cam_eye=CAMERA.astype(np.float32),
        lobe=phong_table(np.array([0.3, 0.28, 0.32]), 20.0),
        lobe_half=False,
    )
    if method == "paper":
        ww = np.array([[0.85, 0.06, 0.02], [0.05, 0.9, 0.05], [0.02, 0.07, 0.8]], np.float32)
        wc = (screen[:, None] * ww + 0.02).astype(np.float32)
        scale = np.array([0.95, 0.8, 0.7])  # rho_c(l) = scale * l^gam
        return RuntimeModel(
            method="paper",
            fwd_lut=fwd,
            inv_lut=inv,  # (v / scale)^(1/gam) at v = y * scale
            inv_lo=np.zeros(3, np.float32),
            inv_hi=scale.astype(np.float32),
            Ww=ww,
            Wc_inv=np.linalg.inv(wc.astype(np.float64)).astype(np.float32),
            Aw=np.zeros((height, width, 3), np.float32),
            Ac=np.zeros((height, width, 3), np.float32),
            **common,  # type: ignore[arg-type]
        )
    if method != "pixel":
        raise ValueError(f"method must be 'pixel' or 'paper', got {method!r}")
    f = _smooth_field(rng, height, width, 18)
    eye3 = np.eye(3, dtype=np.float32)
    off = 0.05 + 0.03 * f[..., :9].reshape(height, width, 3, 3)
    ww = (eye3 * (0.8 + 0.1 * f[..., 9:12])[..., None] + (1 - eye3) * off).astype(np.float32)
    wc_diag = screen * (0.85 + 0.1 * f[..., 12:15])
    wc = (eye3 * wc_diag[..., None] + (1 - eye3) * 0.6 * off.transpose(0, 1, 3, 2)).astype(
        np.float32
    )
    aw = (0.015 + 0.005 * f[..., 15:18]).astype(np.float32)
    ac = (aw * screen).astype(np.float32)
    return RuntimeModel(
        method="pixel",
        fwd_lut=fwd,
        inv_lut=inv,
        inv_lo=np.zeros(3, np.float32),
        inv_hi=np.ones(3, np.float32),
        Ww=ww,
        Wc=wc,
        Aw=aw,
        Ac=ac,
        **common,  # type: ignore[arg-type]
    )


def smooth_frame(width: int, height: int, seed: int = 0) -> np.ndarray:
    """A smooth colourful test frame (H, W, 3) uint8 covering most of 0..255."""
    rng = np.random.default_rng(seed)
    f = _smooth_field(rng, height, width, 3)
    xx = np.linspace(0.0, 1.0, width, dtype=np.float32)[None, :, None]
    img = 0.5 + 0.35 * f + 0.15 * (xx - 0.5) * 2.0
    return np.clip(np.rint(255.0 * img), 0, 255).astype(np.uint8)


def uniform_frame(
    width: int, height: int, rgb: tuple[int, int, int] = (128, 96, 160)
) -> np.ndarray:
    """A uniform frame (H, W, 3) uint8 of one colour."""
    return np.broadcast_to(np.array(rgb, np.uint8), (height, width, 3)).copy()


def make_test_video(
    path: str,
    width: int = 320,
    height: int = 180,
    seconds: float = 2.0,
    rate: int = 25,
    audio: bool = True,
    audio_codec: str = "aac",
    sample_rate: int = 48000,
    codec: str = "libx264",
) -> None:
    """Write a synthetic clip: moving smooth colours and, if ``audio``, a 440 Hz sine tone.

    yuv420p H.264 (ultrafast) at ``rate`` fps for ``seconds``; the audio (mono) lasts as long.
    """
    n = round(seconds * rate)
    base = smooth_frame(width + n, height, seed=1)
    frames = (np.ascontiguousarray(base[:, i : i + width]) for i in range(n))
    options = {"preset": "ultrafast", "crf": "20"} if codec == "libx264" else None
    write_clip(
        path,
        frames,
        rate,
        tone=audio,
        audio_codec=audio_codec,
        sample_rate=sample_rate,
        codec=codec,
        options=options,
    )


@dataclass(frozen=True)
class SyntheticParams:
    """What :class:`SyntheticCompensation` returns per frame (like ``FrameParams``)."""

    model: RuntimeModel
    alpha: float
    beta: float


class SyntheticCompensation:
    """A stand-in for ``Compensation`` on a fixed :class:`RuntimeModel`.

    Args:
        model: the runtime model (its method and grid are this object's).
        tone: ``(alpha, beta)``, or ``thumb (h, w, 3) uint8 -> (alpha, beta)``.
        eye_dependent: for ``paper``, return a different (cached) model per eye, as the real
            one does: Wc_inv scaled by 1 + 0.1 cos(angle of the eye), inv_hi likewise.

    ``calls`` counts the frames asked for, ``times`` keeps each ``t``, ``thumb_shape`` the
    last thumbnail's shape.
    """

    def __init__(
        self,
        model: RuntimeModel,
        tone: tuple[float, float] | Callable[[np.ndarray], tuple[float, float]] = (0.55, 0.02),
        eye_dependent: bool = False,
    ) -> None:
        self.model = model
        self.method = model.method
        self.tone = tone
        self.eye_dependent = eye_dependent and model.method == "paper"
        self._cache: dict[tuple[float, ...], RuntimeModel] = {}
        self.calls = 0
        self.times: list[float | None] = []
        self.thumb_shape: tuple[int, ...] | None = None

    @property
    def shape(self) -> tuple[int, int]:
        """(H, W) of the grid."""
        return self.model.shape

    def base_model(self) -> RuntimeModel:
        """The model (paper: at the calibration camera)."""
        return self.model

    def model_at(self, eye: np.ndarray) -> RuntimeModel:
        """The model for an eye: the same object unless ``eye_dependent``."""
        if not self.eye_dependent:
            return self.model
        key = tuple(np.round(np.asarray(eye, np.float64), 5))
        m = self._cache.get(key)
        if m is None:
            k = 1.0 + 0.1 * math.cos(math.atan2(float(eye[2]), float(eye[0])))
            m = replace(
                self.model,
                Wc_inv=(self.model.Wc_inv * np.float32(k)).astype(np.float32),  # type: ignore[operator]
                inv_hi=(self.model.inv_hi * np.float32(k)).astype(np.float32),
            )
            self._cache[key] = m
        return m

    def __call__(self, thumb: np.ndarray, eye: np.ndarray, t: float | None = None) -> Any:
        if thumb.ndim != 3 or thumb.shape[2] != 3 or thumb.dtype != np.uint8:
            raise ValueError(f"thumbnail must be (h, w, 3) uint8, got {thumb.dtype} {thumb.shape}")
        self.calls += 1
        self.times.append(t)
        self.thumb_shape = thumb.shape
        alpha, beta = self.tone(thumb) if callable(self.tone) else self.tone
        return SyntheticParams(self.model_at(eye), float(alpha), float(beta))


def make_compensation(
    method: str = "pixel", width: int = 64, height: int = 32, tau: float | None = None
) -> Compensation:
    """A real ``Compensation`` of ``method`` on a simulated glossy magenta screen
    (``tests.support.calibrations.small_calibration``) at width x height, smoothed over
    ``tau`` seconds."""
    return Compensation(small_calibration(w=width, h=height), method, tau=tau)
