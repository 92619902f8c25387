"""The CPU side of compensating frames: what the per-pixel formula needs for each frame.

Both backends (numpy reference, GLSL shader), stills and video, go through one object:

    comp = Compensation(calibration, method="pixel")
    p = comp(thumbnail, eye, t)       # model, alpha, beta for this frame
    out = reference.compensate(p.model, frame, eye, p.alpha, p.beta)   # or the shader

For ``pixel`` the model is fixed and only the tone map (Eq. 22 on the thumbnail) changes per
frame. For ``paper`` the model itself depends on the eye (the predicted calibration images,
Eq. 10) and on the content (the feedback of Eq. 25, with mean(I_c) taken over the
thumbnail); models are cached per (eye, gains) so an unchanged frame costs nothing.
With ``tau`` set, (alpha, beta) are smoothed over time so brightness does not flicker.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import cv2
import numpy as np

from viewcomp.calib.comp.adaptive import AdaptedPrediction, choose_field
from viewcomp.calib.comp.shots import FieldSmoother
from viewcomp.calib.comp.tonemap import (
    DEFAULT_LAMBDA,
    ToneMap,
    ToneSmoother,
    choose_predicted_tone_map,
    choose_tone_map,
)
from viewcomp.calib.io.patterns import GRAY_LEVEL
from viewcomp.calib.model.gamut import ToneField
from viewcomp.calib.model.reference import (
    View,
    audience_solve,
    compensate,
    screen_at,
    tone_terms,
    white_response,
)
from viewcomp.calib.model.runtime import RuntimeModel
from viewcomp.calib.world.audience import Audience

if TYPE_CHECKING:
    from viewcomp.calib.fit.calibrate import Calibration

THUMB_SIDE = 64
#: How the tone map is chosen: the paper's Eq. 21/22, today's global rule, the adaptive field.
TONES = ("paper", "global", "adaptive")
#: Video frames between two whole-grid searches of the per-pixel method's tone map.
FULL_SEARCH_FRAMES = 15
_CACHE = 64


def as_view(eye: View) -> View:
    """One eye as float64 (3,); an audience of one as its eye; a larger one as it is."""
    if isinstance(eye, Audience):
        return eye.eyes[0].copy() if len(eye) == 1 else eye
    return np.asarray(eye, np.float64)


def thumbnail(frame: np.ndarray, max_side: int = THUMB_SIDE) -> np.ndarray:
    """A small (h, w, 3) uint8 thumbnail of an RGB frame, longest side <= ``max_side``.

    Area-averaged (cv2.INTER_AREA); the tone map's statistics come from it.
    """
    h, w = frame.shape[:2]
    s = min(1.0, max_side / max(h, w))
    size = (max(1, round(w * s)), max(1, round(h * s)))
    return cv2.resize(frame, size, interpolation=cv2.INTER_AREA)


def sample_grid(shape: tuple[int, int], small: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Row and column indices of the full grid nearest to each thumbnail pixel's centre."""
    (h, w), (sh, sw) = shape, small
    rows = np.clip(np.rint((np.arange(sh) + 0.5) * h / sh - 0.5), 0, h - 1).astype(int)
    cols = np.clip(np.rint((np.arange(sw) + 0.5) * w / sw - 0.5), 0, w - 1).astype(int)
    return rows, cols


def _sample_model(model: RuntimeModel, rows: np.ndarray, cols: np.ndarray) -> RuntimeModel:
    from dataclasses import replace

    def sub(a: np.ndarray | None, ndim: int) -> np.ndarray | None:
        return a if a is None or a.ndim < ndim else a[rows][:, cols]

    return replace(
        model,
        refl=model.refl[rows][:, cols],
        pos=model.pos[rows][:, cols],
        Ww=model.Ww if model.Ww.ndim < 4 else model.Ww[rows][:, cols],
        Wc=sub(model.Wc, 4),
        Aw=sub(model.Aw, 3),
        Ac=sub(model.Ac, 3),
    )


@dataclass(frozen=True)
class FrameParams:
    """What one frame needs: the runtime model and the tone map (smoothed if asked)."""

    model: RuntimeModel
    alpha: float
    beta: float
    tone: ToneMap
    gains: np.ndarray | None = None
    field: ToneField | None = None  # the adaptive tone map (then alpha, beta are unused)


class Compensation:
    """Per-frame parameters for one calibration and one method.

    Args:
        cal: the calibration (both methods).
        method: "pixel" or "paper".
        lam: the tone map's lambda (Eq. 22).
        tau: time constant (s) of the tone map's smoothing over video frames; None: none.
        feedback: iterations of the paper's Eq. 25 feedback for a still (the paper: 3); for
            video frames (called with a time ``t``) one iteration per frame, carried over.
        tone: how the tone map is chosen (:data:`TONES`): ``paper`` Eq. 21/22 (the paper
            method's only choice), ``global`` one (alpha, beta) of the smallest predicted
            error (the pixel method's default), ``adaptive`` the smooth field with the
            hue-keeping soft clip (pixel method, one eye; :mod:`~viewcomp.calib.comp.adaptive`),
            smoothed within a shot and reset at a cut (:class:`FieldSmoother`).
    """

    def __init__(
        self,
        cal: Calibration,
        method: str = "pixel",
        lam: float = DEFAULT_LAMBDA,
        tau: float | None = None,
        feedback: int = 3,
        tone: str | None = None,
    ) -> None:
        if method not in ("pixel", "paper"):
            raise ValueError(f"method must be 'pixel' or 'paper', got {method!r}")
        tone = tone or ("global" if method == "pixel" else "paper")
        if tone not in TONES or (method == "paper" and tone != "paper"):
            raise ValueError(
                f"tone must be one of {TONES} (the paper's method: 'paper'), got {tone!r}"
            )
        self.tone = tone
        self.fields = FieldSmoother(tau if tau else 0.0)
        cal.require(method)
        self.cal = cal
        self.method = method
        self.lam = float(lam)
        self.feedback = int(feedback)
        self.smoother = ToneSmoother(tau) if tau else None
        self._pixel_model = cal.pixel.runtime_model() if method == "pixel" else None
        self._small: dict[tuple[int, int], tuple[np.ndarray, np.ndarray, RuntimeModel]] = {}
        self._paper: OrderedDict[tuple, RuntimeModel] = OrderedDict()
        self._gains: np.ndarray | None = None  # the paper's feedback, carried between frames
        self._view: tuple | None = None  # the screen at the last eye or audience (_screen)
        self._last_tone: ToneMap | None = None  # the last video frame's, unsmoothed
        self._frames = 0  # video frames since the last full tone-map search

    @property
    def shape(self) -> tuple[int, int]:
        """(H, W) of the projector grid."""
        return self.cal.shape

    def base_model(self) -> RuntimeModel:
        """A model of the right method and grid (the paper's: at the calibration camera)."""
        if self._pixel_model is not None:
            return self._pixel_model
        assert self.cal.paper is not None  # Compensation() required the paper's method
        return self.paper_model(self.cal.paper.geometry.camera, np.ones(3))

    def paper_model(self, eye: np.ndarray, gains: np.ndarray) -> RuntimeModel:
        """The paper's runtime model at ``eye`` with feedback gains i_c/i_s, cached."""
        key = (*np.round(np.asarray(eye, float), 5), *np.round(gains, 3))
        m = self._paper.get(key)
        if m is None:
            assert self.cal.paper is not None  # Compensation() required the paper's method
            m = self.cal.paper.runtime_model(np.asarray(eye, float), np.round(gains, 3))
            self._paper[key] = m
            if len(self._paper) > _CACHE:
                self._paper.popitem(last=False)
        else:
            self._paper.move_to_end(key)
        return m

    def _small_model(self, model: RuntimeModel, shape: tuple[int, int]) -> RuntimeModel:
        if model.method == "paper":
            rows, cols = self._grid(shape)
            return _sample_model(model, rows, cols)
        hit = self._small.get(shape)
        if hit is None:
            rows, cols = self._grid(shape)
            hit = (rows, cols, _sample_model(model, rows, cols))
            self._small[shape] = hit
        return hit[2]

    def _grid(self, shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
        return sample_grid(self.shape, shape)

    def tone_map(
        self,
        model: RuntimeModel,
        thumb: np.ndarray,
        eye: View,
        start: ToneMap | None = None,
    ) -> ToneMap:
        """The tone map for the thumbnail, this model and eye (unsmoothed): the paper's
        method Eq. 22; the per-pixel method the smallest predicted perceptual error
        (:func:`~viewcomp.calib.comp.tonemap.choose_predicted_tone_map`; ``start``: a local
        search from a previous choice)."""
        small = self._small_model(model, thumb.shape[:2])
        cw = white_response(small, thumb).astype(np.float64)
        if model.method == "paper":
            assert model.Wc_inv is not None  # a paper model always has it
            u = cw @ model.Wc_inv.T.astype(np.float64)
            v = np.broadcast_to(model.Wc_inv.astype(np.float64) @ np.ones(3), u.shape)
            return choose_tone_map(u, v, 0.0, model.inv_lo, model.inv_hi, self.lam)
        if self.tone == "paper" and not isinstance(eye, Audience):
            m, m_inv, a = self._screen(small, eye)
            u, v, c = tone_terms(m_inv, cw, a)
            return choose_tone_map(u, v, c, 0.0, 1.0, self.lam)
        if isinstance(eye, Audience):
            mk, ak, p, d = self._audience(small, eye)
            u = np.einsum("...ij,...j->...i", p, cw)
            viewers = (mk, ak, eye.weights)
            return choose_predicted_tone_map(
                u, p.sum(axis=-1), -d, mk[0], cw, 0.0, 1.0, start, viewers
            )
        m, m_inv, a = self._screen(small, eye)
        u, v, c = tone_terms(m_inv, cw, a)
        return choose_predicted_tone_map(u, v, c, m, cw, 0.0, 1.0, start)

    def _screen(
        self, small: RuntimeModel, eye: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The screen at ``eye`` on the thumbnail's pixels (float64): M, M^-1 and A, kept for
        the last (grid, eye) asked for, so a held eye costs the inversion once."""
        key = (small.shape, tuple(np.asarray(eye, np.float64).tolist()))
        if self._view is None or self._view[0] != key:
            m, a = screen_at(small, eye)
            m64 = m.astype(np.float64)
            self._view = (key, m64, np.linalg.inv(m64), a.astype(np.float64))
        return self._view[1], self._view[2], self._view[3]

    def _audience(
        self, small: RuntimeModel, audience: Audience
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """An audience on the thumbnail's pixels (float64): every viewer's M_k (K, h, w, 3,
        3) and A_k (K, h, w, 3), and the solve's P and d (:func:`audience_solve`), kept for
        the last (grid, audience) asked for."""
        key = (small.shape, audience.key)
        if self._view is None or self._view[0] != key:
            screens = [screen_at(small, e) for e in audience.eyes]
            mk = np.stack([m for m, _ in screens]).astype(np.float64)
            ak = np.stack([a for _, a in screens]).astype(np.float64)
            p, d = audience_solve(small, audience)
            self._view = (key, mk, ak, p.astype(np.float64), d.astype(np.float64))
        return self._view[1], self._view[2], self._view[3], self._view[4]

    def __call__(
        self,
        thumb: np.ndarray,
        eye: View,
        t: float | None = None,
        cut: bool | None = None,
        early: Callable[[FrameParams], None] | None = None,
        stop: Callable[[], bool] | None = None,
    ) -> FrameParams:
        """Parameters for a frame from its thumbnail (h, w, 3) uint8, the eye (3,) metres or
        an :class:`Audience` (pixel method), the time (s). ``cut``: whether a new shot began
        since the last call, as the caller's :class:`~viewcomp.calib.comp.shots.ShotDetector`
        saw it on every frame (a caller that skips frames); None: detected here from the
        thumbnails given (a caller that gives every frame). ``early``: at a cut in video with
        the adaptive field, called with the new shot's first-stage parameters (the best
        uniform field) before its node search ends, for a caller on another thread to show
        meanwhile (the tone worker); the returned parameters replace them. ``stop``: asked
        during the adaptive field's node search; True gives the call up
        (:class:`~viewcomp.calib.comp.adaptive.SearchStopped`, the field's state as before
        the call: the tone worker's newer request, a cut, goes first)."""
        eye = as_view(eye)
        if isinstance(eye, Audience) and self.method != "pixel":
            raise ValueError("an audience of several viewers needs the pixel method")
        gains = None
        if self.method == "pixel":
            model = self._pixel_model
            assert model is not None  # made in __init__ for the pixel method
            # Video: a local search from the last frame's choice, the whole grid every
            # FULL_SEARCH_FRAMES frames (a scene cut) and for stills.
            warm = t is not None and self._frames % FULL_SEARCH_FRAMES != 0
            tone = self.tone_map(model, thumb, eye, self._last_tone if warm else None)
            if t is not None:
                self._last_tone = tone
                self._frames += 1
        else:
            # Stills: the paper's three feedback iterations from i_c = i_s. Video (t given):
            # the iteration carries over from frame to frame, one step per frame, starting
            # from the previous frame's gains - the same fixed point, spread over time.
            assert not isinstance(eye, Audience)  # refused above for the paper's method
            video = t is not None and self._gains is not None
            gains = self._gains if video and self._gains is not None else np.ones(3)
            model = self.paper_model(eye, gains)
            tone = self.tone_map(model, thumb, eye)
            for _ in range(1 if video else self.feedback):
                small = self._small_model(model, thumb.shape[:2])
                out = compensate(small, thumb, eye, tone.alpha, tone.beta)
                gains = out.reshape(-1, 3).mean(axis=0) / GRAY_LEVEL
                model = self.paper_model(eye, gains)
                tone = self.tone_map(model, thumb, eye)
            if t is not None:
                self._gains = gains
        alpha, beta = tone.alpha, tone.beta
        if self.tone == "adaptive" and not isinstance(eye, Audience):
            assert model is not None
            m = model

            def first(f: ToneField) -> None:
                if early is not None:
                    early(FrameParams(m, alpha, beta, tone, gains, f))

            field = self._field(model, thumb, eye, tone, t, cut, first, stop)
            return FrameParams(model, alpha, beta, tone, gains, field)
        if self.smoother is not None and t is not None:
            alpha, beta = self.smoother.update(t, alpha, beta)
        return FrameParams(model, alpha, beta, tone, gains)

    def _field(
        self,
        model: RuntimeModel,
        thumb: np.ndarray,
        eye: np.ndarray,
        tone: ToneMap,
        t: float | None,
        cut: bool | None = None,
        early: Callable[[ToneField], None] | None = None,
        stop: Callable[[], bool] | None = None,
    ) -> ToneField:
        """The adaptive field for a frame: a whole search for a still and at a cut, a local
        one from the last frame's within a shot; smoothed over a shot's frames."""
        small = self._small_model(model, thumb.shape[:2])
        m, m_inv, a = self._screen(small, eye)
        cw = white_response(small, thumb).astype(np.float64)
        pred = AdaptedPrediction(*tone_terms(m_inv, cw, a), m, a, cw)
        if t is None:
            return choose_field(pred, (tone.alpha, tone.beta))
        cut = self.fields.is_cut(thumb) if cut is None else cut
        last = None if cut else self.fields.raw
        field = choose_field(
            pred, (tone.alpha, tone.beta), last, early=early if cut else None, stop=stop
        )
        return self.fields.update(t, field, cut)

    def compensate_image(
        self, image: np.ndarray, eye: View, identity: bool = False
    ) -> tuple[np.ndarray, FrameParams]:
        """The numpy reference end to end for one image already on the projector grid."""
        eye = as_view(eye)
        p = self(thumbnail(image), eye)
        out = compensate(p.model, image, eye, p.alpha, p.beta, identity=identity, field=p.field)
        return out, p
