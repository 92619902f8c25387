"""The paper's Section 5 in the simulator (docs/MODEL.md section 5): table2, sweep, oracle.

What is compared, always: T_i is the test image projected on the ideal matte white screen
and seen by the ideal eye (no noise, no vignetting, 8-bit) at the eye position of the row;
T_t is a compensated (or the original) image projected on the real screen and seen by the
same eye. Columns:

- ``original``: I_w itself projected on the real screen (T_o);
- ``paper_90`` / ``pixel_90``: compensated for 90 degrees (the calibration camera's view);
- ``paper_theta`` / ``pixel_theta``: compensated for the angle the row is seen at;
- ``paper_60`` / ``pixel_60``: compensated for 60 degrees (the paper's T_60; at rows seen at
  90 this is the paper's "T_60 seen at 90" column of Table 2);
- ``oracle``: the physical limit: the simulator's true per-pixel model at the eye inverted
  exactly, with the per-pixel method's tone-map rule (the smallest predicted colour error,
  predicted by the true model).

Calibrations come from simulated 8-bit captures through the same code as `viewcomp
calibrate`; compensations from the same code as `viewcomp render --backend cpu`.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np

from viewcomp.calib.comp.compensation import Compensation, sample_grid, thumbnail
from viewcomp.calib.comp.tonemap import (
    DEFAULT_LAMBDA,
    ToneMap,
    choose_predicted_tone_map,
)
from viewcomp.calib.eval.adapted import adapted_delta_e
from viewcomp.calib.eval.limit import physical_limit
from viewcomp.calib.eval.metrics import delta_e2000, psnr, sse, ssim
from viewcomp.calib.eval.testimages import natural_images, uniform
from viewcomp.calib.fit.calibrate import Calibration, calibrate
from viewcomp.calib.io.captureset import capture_set_from_raw
from viewcomp.calib.model.reference import tone_terms
from viewcomp.calib.sim.simcamera import SimCamera
from viewcomp.calib.sim.simulate import capture_patterns
from viewcomp.calib.sim.simulator import (
    Screen,
    Simulator,
    make_screen,
    simulation_rig,
    white_screen,
)

TABLE2_SCREENS = ("red", "green", "blue")
TABLE2_IMAGES = ((100, 50, 50), (50, 100, 50), (50, 50, 100))
TABLE2_ANGLES = (90, 60)
SWEEP_SCREENS = ("red", "green", "blue", "magenta")
SWEEP_ANGLES = (30, 45, 60, 75, 90, 105, 120, 135, 150)
KEYS = ("original", "paper_90", "paper_theta", "pixel_90", "pixel_theta", "oracle")

Progress = Callable[[str], None]


@dataclass
class Case:
    """One simulated screen with its calibration and compensators."""

    name: str
    screen: Screen
    cal: Calibration
    paper: Compensation
    pixel: Compensation


@dataclass
class World:
    """The simulator and the white screen's captures, shared by every case."""

    sim: Simulator
    white_raw: dict[str, np.ndarray]
    gloss: str | tuple[float, float]
    lam: float
    space: str = "projector"  # "camera": captures seen by the simulated camera, rectified
    camera: SimCamera | None = None  # the simulated camera, for space = "camera"
    #: calibrate's colour guide (None: its default for the space; 0: none)
    guide_px: int | None = None

    @classmethod
    def make(
        cls,
        seed: int = 0,
        gloss: str | tuple[float, float] = "glossy",
        lam: float = DEFAULT_LAMBDA,
        size: tuple[int, int] | None = None,
        projector_fov: float | None = None,
        space: str = "projector",
    ) -> World:
        """The evaluation world on the simulation rig (optionally another size or fov).

        ``space = "camera"``: every case's captures are what the simulated camera sees (lens,
        pose, blur, surround; chessboard and Gray code included) and `calibrate` rectifies
        them, as for a real camera; with ``size`` the camera's resolution scales with the
        projector's. The eye that judges the results is the same in both spaces.
        """
        from dataclasses import replace

        rig = simulation_rig()
        proj = rig.projector
        if size is not None:
            proj = replace(proj, resolution=size, principal_point=None)
        if projector_fov is not None:
            proj = replace(proj, fov_y=projector_fov)
        rig = replace(rig, projector=proj)
        if space == "camera":
            from viewcomp.calib.sim.simcamera import (
                camera_simulator,
                capture_camera_patterns,
                scaled_camera_rig,
            )

            sim = camera_simulator(scaled_camera_rig(rig, size), seed)
            cam = SimCamera(sim)
            white = capture_camera_patterns(cam, white_screen(), geometric="chessboard")
            return cls(sim, white, gloss, lam, space, cam)
        if space != "projector":
            raise ValueError(f'space must be "projector" or "camera", got {space!r}')
        sim = Simulator(rig=rig, seed=seed)
        return cls(sim, capture_patterns(sim, white_screen()), gloss, lam)

    @property
    def shape(self) -> tuple[int, int]:
        """(H, W) of the projector grid."""
        return self.sim.shape

    def eye(self, angle: float) -> np.ndarray:
        """The eye at a viewing angle, at the rig's viewer distance and height."""
        v = self.sim.rig.viewer
        return v.eye(angle)

    def case(self, name: str) -> Case:
        """Simulate, capture and calibrate one screen."""
        screen = make_screen(name, self.gloss, shape=self.shape, seed=self.sim.seed)
        if self.camera is not None:
            from viewcomp.calib.sim.simcamera import capture_camera_patterns, written_rig

            raw = capture_camera_patterns(self.camera, screen)
            rig = written_rig(self.sim.rig)  # the lens is for calibrate to estimate
            cs = capture_set_from_raw(rig, self.white_raw, raw)
        else:
            raw = capture_patterns(self.sim, screen)
            cs = capture_set_from_raw(self.sim.rig, self.white_raw, raw)
        cal = calibrate(cs, guide_px=self.guide_px)
        return Case(
            name,
            screen,
            cal,
            Compensation(cal, "paper", self.lam),
            Compensation(cal, "pixel", self.lam),
        )

    def limit(self, screen: Screen, ideal: np.ndarray, angle: float) -> float:
        """The per-pixel physical limit of the adapted error
        (:func:`~viewcomp.calib.eval.limit.physical_limit`) of ``screen`` seen at ``angle``,
        on about 160 x 80 of its pixels."""
        sim, eye = self.sim, self.eye(angle)
        return physical_limit(
            sim.true_mixing(screen, eye, vignetting=False),
            sim.true_ambient(screen, vignetting=False),
            sim.projector.response(np.zeros(3)),
            sim.projector.response(np.full(3, 255.0)),
            ideal,
            sim.response,
            step=max(2, round(self.shape[1] / 160)),
        ).de

    def oracle(self, screen: Screen, image: np.ndarray, eye: np.ndarray) -> np.ndarray:
        """The physical limit: invert the true per-pixel model at ``eye`` exactly.

        Target: the white screen seen by the same eye, alpha C_w + beta with the tone map
        chosen by the per-pixel method's rule (the smallest predicted perceptual error, here
        predicted by the true model) on the same thumbnail; the bounds are the projector's
        true range [f(0), f(255)].
        """
        sim = self.sim
        mw = sim.true_mixing(white_screen(), eye, vignetting=False)
        aw = sim.true_ambient(white_screen(), vignetting=False)
        mc = sim.true_mixing(screen, eye, vignetting=False)
        ac = sim.true_ambient(screen, vignetting=False)
        cw = np.einsum("hwij,hwj->hwi", mw, sim.projector.response(image)) + aw
        m_inv = np.linalg.inv(mc)
        thumb = thumbnail(image)
        rows, cols = sample_grid(self.shape, thumb.shape[:2])
        sub = (rows[:, None], cols[None, :])
        proj = sim.projector
        cw_s = np.einsum("hwij,hwj->hwi", mw[sub], proj.response(thumb)) + aw[sub]
        tone = choose_predicted_tone_map(
            *tone_terms(m_inv[sub], cw_s, ac[sub]),
            mc[sub],
            cw_s,
            proj.response(np.zeros(3)),
            proj.response(np.full(3, 255.0)),
        )
        pu, pv, pc = tone_terms(m_inv, cw, ac)
        p = tone.alpha * pu + tone.beta * pv + pc
        return np.rint(sim.projector.response_inverse(p)).astype(np.uint8)


def _compensations(
    world: World, case: Case, image: np.ndarray, angles: Iterable[float]
) -> tuple[dict[str, np.ndarray], dict[str, ToneMap]]:
    out: dict[str, np.ndarray] = {}
    tones: dict[str, ToneMap] = {}
    for a in angles:
        eye = world.eye(a)
        for method, comp in (("paper", case.paper), ("pixel", case.pixel)):
            img, p = comp.compensate_image(image, eye)
            out[f"{method}_{a:g}"] = img
            tones[f"{method}_{a:g}"] = p.tone
    return out, tones


def _seen(
    world: World, case: Case, image: np.ndarray, comps: dict[str, np.ndarray], seen: float
) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """What the eye at ``seen`` sees of every column, and the ideal T_i."""
    eye = world.eye(seen)
    t_i = world.sim.observe(white_screen(), image, eye)
    views = {"original": world.sim.observe(case.screen, image, eye)}
    for k, img in comps.items():
        views[k] = world.sim.observe(case.screen, img, eye)
    views["oracle"] = world.sim.observe(case.screen, world.oracle(case.screen, image, eye), eye)
    views["paper_theta"] = views[f"paper_{seen:g}"]
    views["pixel_theta"] = views[f"pixel_{seen:g}"]
    return views, t_i


def table2(world: World, progress: Progress | None = None) -> list[dict[str, Any]]:
    """The paper's Table 2 protocol: 3 glossy screens x 3 uniform images x seen at 90, 60.

    Each row: screen, image [R, G, B], seen_at, and per column ``sse`` (Eq. 26, 8-bit units,
    over the whole projector image), ``psnr`` (dB), ``ssim`` and ``de`` (mean CIEDE2000),
    each comparing that column's view with T_i. Columns: see the module docstring.
    """
    h, w = world.shape
    rows = []
    for name in TABLE2_SCREENS:
        case = world.case(name)
        for rgb in TABLE2_IMAGES:
            image = uniform(rgb, w, h)
            comps, tones = _compensations(world, case, image, TABLE2_ANGLES)
            for seen in TABLE2_ANGLES:
                views, t_i = _seen(world, case, image, comps, seen)
                cols = (*KEYS, "paper_60", "pixel_60")
                rows.append(
                    {
                        "screen": name,
                        "image": list(rgb),
                        "seen_at": seen,
                        "sse": {k: sse(views[k], t_i) for k in cols},
                        "psnr": {k: psnr(views[k], t_i) for k in cols},
                        "ssim": {k: ssim(views[k], t_i) for k in cols},
                        "de": {k: delta_e2000(views[k], t_i) for k in cols},
                        "ade": {k: adapted_delta_e(views[k], t_i).de for k in cols},
                        "tone": {
                            k: [round(t.alpha, 3), round(t.beta, 5)] for k, t in tones.items()
                        },
                    }
                )
            if progress:
                progress(f"table2: {name} screen, image {list(rgb)} done")
    return rows


def sweep(
    world: World,
    screens: Iterable[str] = SWEEP_SCREENS,
    angles: Iterable[float] = SWEEP_ANGLES,
    images: dict[str, np.ndarray] | None = None,
    progress: Progress | None = None,
    keep: dict[str, Any] | None = None,
) -> list[dict[str, Any]]:
    """Natural test images on glossy screens seen at angles 30..150: mean CIEDE2000 per column.

    ``keep``, when given, receives the views of the first screen and image for the plots.
    """
    h, w = world.shape
    imgs = images if images is not None else natural_images(w, h)
    angles = list(angles)
    rows = []
    for name in screens:
        case = world.case(name)
        for iname, image in imgs.items():
            comps, _ = _compensations(world, case, image, [90])
            for a in angles:
                more, _ = _compensations(world, case, image, [a]) if a != 90 else ({}, {})
                views, t_i = _seen(world, case, image, {**comps, **more}, a)
                rows.append(
                    {
                        "screen": name,
                        "image": iname,
                        "seen_at": a,
                        "de": {k: delta_e2000(views[k], t_i) for k in KEYS},
                        "ade": {k: adapted_delta_e(views[k], t_i).de for k in KEYS},
                        "limit": world.limit(case.screen, t_i, a),
                    }
                )
                if keep is not None and not keep.get("done"):
                    keep.setdefault("views", {})[a] = {k: views[k] for k in KEYS} | {"ideal": t_i}
                    keep["screen"], keep["image"] = name, iname
            if keep is not None and "views" in keep:
                keep["done"] = True
            if progress:
                progress(f"sweep: {name} screen, image {iname} done")
    return rows


def check_table2(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Table 2's criteria (docs/MODEL.md section 5), counted (not asserted): what holds in
    how many rows."""
    at60 = [r for r in rows if r["seen_at"] == 60]
    at90 = [r for r in rows if r["seen_at"] == 90]

    def count(rs: list[dict[str, Any]], f: Callable[[dict[str, float]], bool]) -> int:
        return sum(1 for r in rs if f(r["sse"]))

    others = [k for k in KEYS if k != "original"]
    return {
        "seen60_paper_theta_lt_paper_90": count(at60, lambda s: s["paper_theta"] < s["paper_90"]),
        "seen90_paper_90_le_paper_theta": count(at90, lambda s: s["paper_90"] <= s["paper_theta"]),
        "seen90_paper_90_le_paper_60": count(at90, lambda s: s["paper_90"] <= s["paper_60"]),
        "original_worst": count(
            rows, lambda s: all(s["original"] > s[k] for k in (*others, "paper_60", "pixel_60"))
        ),
        "pixel_theta_le_paper_theta": count(rows, lambda s: s["pixel_theta"] <= s["paper_theta"]),
        "seen60_pixel_theta_le_half_paper_90": count(
            at60, lambda s: s["pixel_theta"] <= 0.5 * s["paper_90"]
        ),
        "rows_seen60": len(at60),
        "rows_seen90": len(at90),
        "rows": len(rows),
    }


def sweep_means(rows: list[dict[str, Any]]) -> dict[str, dict[str, float]]:
    """Mean dE per column at each angle (over screens and images)."""
    out: dict[str, dict[str, float]] = {}
    for a in sorted({r["seen_at"] for r in rows}):
        rs = [r for r in rows if r["seen_at"] == a]
        out[f"{a:g}"] = {k: float(np.mean([r["de"][k] for r in rs])) for k in KEYS}
    return out


def sweep_adapted_means(rows: list[dict[str, Any]]) -> dict[str, dict[str, float]]:
    """Mean adapted dE per column at each angle, and the per-pixel limit's (``limit``)."""
    out: dict[str, dict[str, float]] = {}
    for a in sorted({r["seen_at"] for r in rows}):
        rs = [r for r in rows if r["seen_at"] == a]
        out[f"{a:g}"] = {k: float(np.mean([r["ade"][k] for r in rs])) for k in KEYS} | {
            "limit": float(np.mean([r["limit"] for r in rs]))
        }
    return out


def check_sweep(means: dict[str, dict[str, float]]) -> dict[str, Any]:
    """The sweep's criteria at every angle: pixel_theta at most paper_theta, and off 90
    degrees pixel_theta at most both 90-degree compensations (docs/EVALUATION.md)."""
    ok1 = {a: m["pixel_theta"] <= m["paper_theta"] for a, m in means.items()}
    ok2 = {
        a: m["pixel_theta"] <= min(m["paper_90"], m["pixel_90"])
        for a, m in means.items()
        if float(a) != 90
    }
    return {
        "pixel_theta_le_paper_theta": ok1,
        "off90_pixel_theta_le_both_90": ok2,
        "all": all(ok1.values()) and all(ok2.values()),
    }


def gap_closed(rows: list[dict[str, Any]], metric: str) -> dict[str, float]:
    """Share of the gap between paper_90 and the oracle that each *_theta column closes.

    (E_paper_90 - E_method) / (E_paper_90 - E_oracle), averaged over rows where the gap is
    positive; 1 means the method reaches the physical limit, 0 means no better than paper_90.
    """
    out = {}
    for k in ("paper_theta", "pixel_theta", "pixel_90"):
        vals = []
        for r in rows:
            m = r[metric]
            gap = m["paper_90"] - m["oracle"]
            if gap > 1e-9:
                vals.append((m["paper_90"] - m[k]) / gap)
        out[k] = float(np.mean(vals)) if vals else float("nan")
    return out


def dumps(report: dict[str, Any]) -> str:
    """report.json text (finite floats only)."""
    return json.dumps(report, indent=1, allow_nan=False)
