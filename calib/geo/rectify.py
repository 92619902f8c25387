"""Geometric calibration of a camera-space capture set: from camera frames to the projector grid.

With ``[capture] space = "camera"`` the captures are raw camera frames (Hc, Wc, 3): the
projector's frame is a distorted quadrilateral in them. Before any of docs/MODEL.md's math, every
capture is rectified onto the projector's pixel grid (H, W), as the paper does with Zhang's
method and a chessboard:

1. **Chessboard** (``screen/chessboard``, and ``white/chessboard`` when present):
   ``cv2.findChessboardCorners`` + ``cv2.cornerSubPix``; the corners' projector coordinates
   are known (:func:`~viewcomp.calib.io.patterns.chessboard`), their points on the screen come
   from the rig's projector. Zhang's method (``cv2.calibrateCamera``) on that one planar
   view, seeded with the rig's intrinsics which stay fixed (one view cannot determine them),
   estimates the lens distortion (k1, k2) and gives the reprojection error.
2. **Gray code** (``screen/graycode_white``, ``graycode_black``, ``graycode_00`` ...; OpenCV
   structured_light's patterns): decoded per camera pixel into the projector column and row
   that light it. Each bit plane is first checked against the chessboard's prediction, so a
   plane out of order is named. **Phase shifting** (``screen/phase_col_0`` ...
   ``phase_row_7``, when captured; :mod:`~viewcomp.calib.geo.phaseshift`): when the camera
   does not resolve the whole Gray code (a camera coarser than the projector's finest
   stripes), the planes it does not resolve are dropped (and not checked), the rest pick the
   sinusoid's period and its phase gives the sub-pixel position, which the map is fitted to
   (on the pixels that see the frame whole). A camera that resolves every plane keeps the
   Gray code's whole pixels (:func:`gray_code_suffices`, with the measurement behind it).
3. **The map** projector pixel -> camera pixel, a smooth model fitted to the decoded pixels
   (robust least squares, started from Zhang's lens and the chessboard's homography):
   camera = K dist(H [s, t, 1]) + r(s, t), with (s, t) the projector pixel scaled to -1..1,
   K the rig's camera matrix, dist OpenCV's (k1, k2, p1, p2) lens refined on the dense
   points, H a homography (exact for a pinhole projector on a plane) and r a cubic
   polynomial correction (what the projector's own lens adds). The Gray code quantises to
   whole projector pixels; the fit over ~10^4 pixels averages that away.
4. **Rectification**: ``cv2.remap`` (bilinear) of every Table-1 capture through the map gives
   float32 (H, W, 3) linear images on the projector grid, as a ``space = "projector"`` set;
   the frame's edge zone, the outer lines the camera saw mixed with the unlit surround
   (measured from the captures, at least one line: :mod:`~viewcomp.calib.geo.edgezone`),
   takes the values of its nearest inner neighbours.

The camera's response comes from rig.toml. It is checked against the captures: light adds
up, so a Gray-code plane and its inverse, linearised, must sum to white + black even where
the optics blur a stripe edge to an intermediate value; :mod:`~viewcomp.calib.geo.camresponse`
finds the response ("linear", "srgb" or a power law) that makes them do so, and a rig
response that misfits grossly is refused with the estimate in the message.

Refusals (:class:`~viewcomp.calib.errors.FitError`, naming the capture and the fix): no
chessboard; Gray code missing, out of order or not covering the projector image; Table-1
captures in the wrong order (or one as dark as black); a saturated chessboard; the camera
moved between captures (the chessboard corners of the two sets, or the projector frame's
edges against the set's reference, screen/graycode_white or white/gray, with highlights and
clipped pixels left out: :class:`~viewcomp.calib.geo.checks.MoveCheck`, shift by more than
:data:`~viewcomp.calib.geo.checks.MOVE_LIMIT_PX`); the projector image not wholly in the
camera's view; a wrong camera response.

Units: camera and projector coordinates are pixels, (x right, y down), pixel centres at
integers; image arrays are indexed ``[row, column]``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from viewcomp.calib.errors import FitError
from viewcomp.calib.geo.camresponse import check_response
from viewcomp.calib.geo.captures import Captures
from viewcomp.calib.geo.checks import (
    MOVE_LIMIT_PX,
    MoveCheck,
    check_coverage,
    check_pattern_order,
)
from viewcomp.calib.geo.chessboard import Corners, find_corners, zhang
from viewcomp.calib.geo.edgezone import edge_widths, fill_edge_zone
from viewcomp.calib.geo.graycode import GrayCode, check_planes, decode_graycode
from viewcomp.calib.geo.phaseshift import PhaseMap, decode_phase, has_phase, with_phase
from viewcomp.calib.geo.projmap import (
    ProjectorMap,
    camera_density,
    fit_map,
    predict_from_chessboard,
    reconstruction_sigma,
    rectify,
)
from viewcomp.calib.io.captureset import OPTIONAL, REQUIRED, CaptureSet
from viewcomp.calib.io.checks import SATURATION_LIMIT
from viewcomp.calib.world.rig import Rig

MIN_DECODED = 0.5  # share of the lit projector frame that must decode
# share of the lit camera pixels the Gray code alone must decode (every plane resolved, every
# bit of the pixel reliable) for the map to be fitted on its whole pixels rather than the phase's
GRAY_SUFFICES = 0.6
MAX_DENSE_POINTS = 12000
BORDER_PX = 1  # projector pixels at the frame's edge, seen half against the unlit surround
#: The captures whose edges measure the edge zone (:mod:`~viewcomp.calib.geo.edgezone`).
EDGE_PATTERNS = ("red", "green", "blue", "gray")


@dataclass
class Geometry:
    """The geometric calibration of a camera-space set: the ``map`` projector -> camera, the
    chessboard ``corners`` of screen/chessboard, the decoded ``graycode`` and JSON-ready
    ``stats`` (reprojection errors in camera pixels, the lens, the largest frame shift)."""

    map: ProjectorMap
    corners: Corners
    graycode: GrayCode
    stats: dict[str, Any]


def gray_code_suffices(gc: GrayCode) -> bool:
    """Whether the Gray code alone places enough pixels for the map: the camera resolves every
    plane and at least :data:`GRAY_SUFFICES` of the lit pixels decode with every bit reliable.

    Measured at 1.2 camera px per projector px (tests/calib/geo/test_geocal.py's world, seeds
    1-3): the map from the Gray code's whole pixels is 0.008-0.009 camera px RMS from the truth
    and its lens k2 0.018-0.034 (truth 0.02); from the phase's sub-pixel positions 0.011-0.012
    px and k2 0.049-0.080. At 0.6 camera px per projector px the Gray code alone decodes 28% of
    the pixels and the phase is needed (tests/calib/geo/test_phaseshift.py).
    """
    decoded = np.count_nonzero(gc.column >= 0) / max(int(np.count_nonzero(gc.lit)), 1)
    return bool(gc.resolved().all() and decoded >= GRAY_SUFFICES)


def _chessboard(
    screen: Captures, white: Captures, rig: Rig
) -> tuple[Corners, np.ndarray, np.ndarray, dict[str, Any]]:
    """Step 1 of the module doc: the real screen's chessboard corners and Zhang's camera
    matrix ``k`` (3, 3) and distortion ``dist`` on them; the white screen's chessboard (when
    captured) must lie where the real screen's does. Returns them and the stats so far
    (``space``, ``chessboard``).

    Raises:
        FitError: a saturated chessboard, one whose corners are not found, or a camera that
            moved between the white screen's captures and the real screen's.
    """
    size = rig.projector.resolution
    cb = screen.get("chessboard")
    sat = screen.saturation.get("chessboard", 0.0)
    if sat > SATURATION_LIMIT:
        raise FitError(
            screen.rel("chessboard"),
            f"{sat:.1%} of its pixel-channels are at the maximum code (saturated): lower the "
            "camera's exposure or the projector's brightness and capture again",
        )
    corners = find_corners(cb, size, screen.rel("chessboard"), *_shading(screen))
    k, dist, zhang_rms = zhang(corners, rig)
    stats: dict[str, Any] = {
        "space": "camera",
        "chessboard": {
            "corners": len(corners.camera),
            "zhang_rms_px": round(zhang_rms, 4),
            "distortion": [round(float(v), 5) for v in dist],
        },
    }
    if white.has("chessboard"):
        wc = find_corners(white.get("chessboard"), size, white.rel("chessboard"), *_shading(white))
        shift = float(np.sqrt(np.mean(np.sum((wc.camera - corners.camera) ** 2, axis=1))))
        stats["chessboard"]["white_vs_screen_px"] = round(shift, 4)
        if shift > MOVE_LIMIT_PX:
            raise FitError(
                white.rel("chessboard"),
                f"its corners lie {shift:.1f} camera px (RMS) from those of "
                f"{screen.rel('chessboard')}: the camera (or the screen plane) moved between the "
                "white screen's captures and the real screen's; fix the camera and capture both "
                "sets again",
            )
    return corners, k, dist, stats


def _shading(caps: Captures) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The set's gray and black (None where missing), what the chessboard is divided by when
    it is not found as it is (:func:`~viewcomp.calib.geo.chessboard.find_corners`)."""
    gray = caps.get("gray") if caps.has("gray") else None
    return gray, caps.get("black") if caps.has("black") else None


def _phase(screen: Captures, gc: GrayCode, mover: MoveCheck) -> tuple[GrayCode, PhaseMap | None]:
    """The phase-shift captures decoded (each axis' checked by ``mover``), when the set has
    them: returns the Gray code with the phase's sub-pixel positions where it does not resolve
    every plane (else as it is), and the phase map, its stats saying whether the map uses it
    (None without phase captures)."""
    if not has_phase(screen):
        return gc, None
    phase = decode_phase(screen, gc, on_axis=lambda n, img: mover(screen, n, img))
    use = not gray_code_suffices(gc)
    if use:
        gc = with_phase(gc, phase)
    return gc, replace(phase, stats={**phase.stats, "used_for_map": use})


def _fit_dense_map(
    gc: GrayCode,
    mask: np.ndarray,
    k: np.ndarray,
    dist: np.ndarray,
    h_cb: np.ndarray,
    size: tuple[int, int],
) -> tuple[ProjectorMap, dict[str, float]]:
    """Step 3 of the module doc: the map fitted on the decoded camera pixels in ``mask``
    (Hc, Wc) bool, thinned to about :data:`MAX_DENSE_POINTS`, starting from the chessboard's
    homography ``h_cb`` (3, 3; projector px -> camera px) and Zhang's ``k``, ``dist``;
    ``size`` the projector's (W, H). Returns the map and its fit stats."""
    ys, xs = np.nonzero(mask)
    step = max(1, int(np.ceil(len(xs) / MAX_DENSE_POINTS)))
    sel = slice(None, None, step)
    cam_pts = np.stack([xs[sel], ys[sel]], 1).astype(np.float64)
    proj_pts = gc.positions()[ys[sel], xs[sel]]  # sub-pixel with phase shifting
    cu, cv = (size[0] - 1) / 2.0, (size[1] - 1) / 2.0
    norm = np.array([[1 / cu, 0, -1], [0, 1 / cv, -1], [0, 0, 1]])
    h0 = h_cb @ np.linalg.inv(norm)
    return fit_map(cam_pts, proj_pts, k, dist, h0, size)


def _check_inside(pmap: ProjectorMap, camera_size: tuple[int, int], screen: Captures) -> None:
    """Every projector pixel must map inside the camera's image (``camera_size`` (Wc, Hc)).

    Raises:
        FitError: some fall outside it.
    """
    cw, ch = camera_size
    mx, my = pmap.grid()
    outside = (mx < -0.5) | (mx > cw - 0.5) | (my < -0.5) | (my > ch - 0.5)
    if outside.any():
        raise FitError(
            screen.rel("graycode_white"),
            f"{outside.mean():.1%} of the projector's pixels fall outside the camera's image: "
            "aim or zoom the camera out so that it sees the whole projected image, with a margin",
        )


def calibrate_geometry(cs: CaptureSet) -> Geometry:
    """Chessboard + Zhang, Gray code, the dense map and the camera-moved checks (steps 1-3 of
    the module doc) for a ``space = "camera"`` capture set.

    Raises:
        FitError: a capture that makes geometric calibration impossible (see module doc).
    """
    t0 = time.perf_counter()
    rig = cs.rig
    size = rig.projector.resolution
    cw, ch = rig.camera.resolution
    shape = (ch, cw)
    screen = Captures(cs, "screen")
    white = Captures(cs, "white")

    # 1. chessboard + Zhang
    corners, k, dist, stats = _chessboard(screen, white, rig)

    # 2. Gray code; the camera must not have moved; each plane checked against the chessboard
    mover = MoveCheck(screen, tied=white.has("chessboard"))
    gc = decode_graycode(screen, size, on_pair=lambda n, img: mover(screen, n, img))
    stats["response"] = check_response(gc, screen.response, "rig.toml")
    # With the phase-shift captures, a camera that does not resolve the whole Gray code gets
    # sub-pixel positions from the phase, unwrapped by the planes it resolves. One that
    # resolves every plane keeps the Gray code's whole pixels: their rounding is unbiased and
    # the fit averages it away, while the phase carries systematic errors of ~0.01 camera px
    # that bias the lens (module doc, step 2). A set without them: the Gray code alone.
    gc, phase = _phase(screen, gc, mover)
    gc_rel = screen.rel(gc.names[0])
    mover.flush(lambda: check_coverage(gc, size, gc_rel))
    for caps in (white, screen):
        for n in (*REQUIRED, *OPTIONAL, "chessboard"):
            if n != "black" and caps.has(n):
                mover(caps, n, caps.get(n), lambda: check_coverage(gc, size, gc_rel))
    stats["max_frame_shift_px"] = round(mover.worst, 4)
    pred, region, h_cb = predict_from_chessboard(corners, k, dist, shape)
    sub = gc.subpixel is not None  # the phase's positions are the map's
    agreement = check_planes(
        gc, screen, pred, region, phase.planes if sub and phase is not None else None
    )
    check_coverage(gc, size, screen.rel(gc.names[0]))
    ok = gc.column >= 0
    lit_frac = float(ok.sum()) / max(int(gc.lit.sum()), 1)
    if lit_frac < MIN_DECODED:
        raise FitError(
            screen.rel(gc.names[0]),
            f"only {lit_frac:.0%} of the lit camera pixels decode to a projector pixel: the "
            "Gray-code captures are blurred, too dark or out of order; focus the camera, check "
            "the exposure and capture them again",
        )

    # 3. the dense map
    # the fit takes the pixels that see the frame whole: at its edge blur biases the phase
    fit_mask = phase.whole if sub and phase is not None else ok
    pmap, fit = _fit_dense_map(gc, fit_mask, k, dist, h_cb, size)
    corner_err = np.linalg.norm(pmap(corners.projector) - corners.camera, axis=1)
    corner_rms = float(np.sqrt(np.mean(corner_err**2)))
    stats["graycode"] = {
        "decoded_fraction_of_lit": round(lit_frac, 4),
        "plane_agreement_min": min(agreement.values()) if agreement else None,
        **fit,
    }
    if phase is not None:
        stats["phase"] = phase.stats
    stats["map"] = {
        "model": "camera = K dist(H [s, t, 1]) + cubic(s, t)",
        "distortion": [round(float(v), 5) for v in pmap.distortion],
        "chessboard_rms_px": round(corner_rms, 4),
    }
    if corner_rms > MOVE_LIMIT_PX:
        raise FitError(
            screen.rel(gc.names[0]),
            f"the Gray-code map misses the chessboard's corners by {corner_rms:.1f} camera px "
            f"(RMS): the camera moved between {screen.rel('chessboard')} and the Gray-code "
            "captures; fix the camera and capture the set again",
        )
    _check_inside(pmap, (cw, ch), screen)

    stats["seconds"] = round(time.perf_counter() - t0, 2)
    return Geometry(pmap, corners, gc, stats)


def rectify_capture_set(
    cs: CaptureSet, check_order: bool = True
) -> tuple[CaptureSet, dict[str, Any]]:
    """Rectify a ``space = "camera"`` capture set onto the projector grid.

    Returns a CaptureSet whose ``white`` and ``screen`` hold the Table-1 captures (and black)
    as float32 (H, W, 3) linear on the projector grid, with saturation fractions measured on
    the projector grid (the rig is unchanged); and the geometric statistics of
    :func:`calibrate_geometry`. ``check_order``: refuse colour captures in the wrong order
    (False for a mono camera's set, whose colours are grey).

    Raises:
        FitError: a capture that makes geometric calibration or rectification impossible.
    """
    t0 = time.perf_counter()
    geo = calibrate_geometry(cs)
    stats = dict(geo.stats)
    maps = geo.map.grid()
    density = camera_density(maps)
    sigma = reconstruction_sigma(density)
    stats["density_camera_px"] = round(density, 3)
    stats["reconstruction_sigma_px"] = sigma
    white, screen = Captures(cs, "white"), Captures(cs, "screen")
    rect: dict[str, dict[str, np.ndarray]] = {"white": {}, "screen": {}}
    fractions: dict[tuple[str, str], float] = {}
    clipped: dict[tuple[str, str], np.ndarray] = {}
    for caps in (white, screen):
        for n in (*REQUIRED, *OPTIONAL):
            if n not in caps.memory:
                continue
            img = caps.get(n)
            rect[caps.sub][n] = rectify(img, maps, sigma)
            # Codes at the top decode to 1.0; a float (HDR) capture, whose raw saturation is 0,
            # holds light above 1 unclipped.
            if caps.saturation.get(n, 0.0) > 0:
                top = rectify((img >= 1.0).astype(np.float32), maps).round()
                fractions[(caps.sub, n)] = float(top.mean())
                clipped[(caps.sub, n)] = np.any(top > 0, axis=-1) if top.ndim == 3 else top > 0
            else:
                fractions[(caps.sub, n)] = 0.0
    # the edge zone, from the lit uniform patterns of both screens (the ramp's own gradient
    # and black's lack of an edge say nothing of it); every capture gets the same, so the
    # per-pixel terms built from several of them stay consistent
    edge = edge_widths(
        (imgs[n] for imgs in rect.values() for n in EDGE_PATTERNS if n in imgs), BORDER_PX
    )
    stats["edge_zone_px"] = edge
    fill_edge_zone((img for imgs in rect.values() for img in imgs.values()), edge)
    if check_order:  # a mono set's colour order shows only in the per-primary basis
        for sub, imgs in rect.items():
            check_pattern_order(imgs, sub)
    stats["seconds"] = round(time.perf_counter() - t0, 2)
    out = CaptureSet(
        rig=cs.rig,
        white=rect["white"],
        screen=rect["screen"],
        raw_max_fraction=fractions,
        path=cs.path,
        extra={},
        clipped=clipped,
    )
    return out, stats
