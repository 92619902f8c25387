"""What the audience will see: the calibration's own forward prediction, side by side.

``viewcomp preview`` and the demo's pictures are built here. A preview predicts, with the
calibration's fitted model (:func:`viewcomp.calib.model.reference.predict_view`), what a
viewer at an eye position sees of one image on the calibrated surface: the white screen
(the target), the uncompensated projection and the compensated one, each as the calibration
camera would record it (its response from rig.toml, 8-bit), with the colour error of each
against the white screen (mean CIEDE2000, :func:`viewcomp.calib.eval.metrics.delta_e2000`).

All three are on one absolute scale: linear light is scaled so that the white screen at the
projector's full output (its 99th percentile over the frame, mean of the channels) lands at
:data:`REFERENCE_WHITE`, whatever the calibration camera's exposure was. In the camera's own
units an under-exposed calibration would compare dark pictures with a dark target, where
CIELAB's differences shrink and the noise it measured hides: a worse calibration would
report a smaller error. On the absolute scale it reports a larger one.

Labels are white text on a dark band above each column, so they read on any picture.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from viewcomp.calib.comp.compensation import Compensation
from viewcomp.calib.eval.metrics import delta_e2000
from viewcomp.calib.fit.calibrate import Calibration
from viewcomp.calib.model.reference import View, predict_view, white_response
from viewcomp.calib.model.runtime import RuntimeModel

BAND = (24, 24, 24)  # RGB of the label bands
TEXT = (255, 255, 255)
METHOD_NAMES = {"pixel": "per-pixel method", "paper": "paper's method"}
#: Linear level (0..1) at which the white screen at the projector's full output is shown: the
#: level a well-exposed calibration capture puts it at (the simulator's default exposure:
#: 0.656), which leaves headroom for a glossy screen's highlight above white.
REFERENCE_WHITE = 0.65


@dataclass
class Preview:
    """One image seen from one eye, predicted by the calibration (all (H, W, 3) uint8).

    ``white``: the white screen; ``uncompensated``: the image projected as it is;
    ``compensated``: the compensated image projected; ``projected``: what the projector
    shows for it. ``de_uncompensated`` / ``de_compensated``: mean CIEDE2000 of those views
    against ``white``.
    """

    white: np.ndarray
    uncompensated: np.ndarray
    compensated: np.ndarray
    projected: np.ndarray
    de_uncompensated: float
    de_compensated: float


def encode8(cal: Calibration, linear: np.ndarray) -> np.ndarray:
    """Linear camera units -> what the calibration camera records (its response, 8-bit)."""
    enc = cal.rig.camera.response_curve().encode(np.clip(linear, 0.0, 1.0).astype(np.float32))
    return np.rint(np.asarray(enc) * 255.0).astype(np.uint8)


def absolute_scale(model: RuntimeModel, shape: tuple[int, int]) -> float:
    """The factor that puts the white screen at the projector's full output at
    :data:`REFERENCE_WHITE`: ``shape`` (H, W) of the frames; the full output's 99th percentile
    (mean of the channels, linear camera units) is measured on the model's white screen."""
    full = white_response(model, np.full((*shape, 3), 255, np.uint8))
    top = float(np.percentile(full.mean(axis=2), 99.0))
    if not (np.isfinite(top) and top > 0):
        raise ValueError(f"the calibration's white screen shows no light at full output ({top})")
    return REFERENCE_WHITE / top


def predict(
    comp: Compensation, image: np.ndarray, eye: np.ndarray, compensate_for: View | None = None
) -> Preview:
    """The preview of ``image`` (H, W, 3) uint8 on the projector grid seen from ``eye``
    (metres), with ``comp``'s method and tone map (a still: no smoothing), compensated for
    ``eye`` or for ``compensate_for`` (another eye, or an audience: what one of its viewers
    sees of the audience's compensation)."""
    eye = np.asarray(eye, np.float64)
    projected, params = comp.compensate_image(
        image, eye if compensate_for is None else compensate_for
    )
    model = params.model
    if comp.method == "paper":  # the paper's model of the screen at this eye, no feedback
        plain = comp.paper_model(eye, np.ones(3))
    else:
        plain = model
    cal = comp.cal
    k = absolute_scale(model, image.shape[:2])
    white = encode8(cal, k * white_response(model, image))
    uncomp = encode8(cal, k * predict_view(plain, image, eye))
    comped = encode8(cal, k * predict_view(model, projected, eye))
    return Preview(
        white, uncomp, comped, projected, delta_e2000(uncomp, white), delta_e2000(comped, white)
    )


def _font_scale(width: int, height: int) -> tuple[float, int]:
    """A font scale and thickness for a band ``height`` pixels high across ``width``."""
    scale = max(0.35, min(1.2, height / 40.0))
    return scale, 2 if scale >= 0.7 else 1


def band(width: int, lines: list[str], height: int = 0) -> np.ndarray:
    """A dark band (h, width, 3) uint8 with ``lines`` of white text, shrunk to fit."""
    import cv2

    line_h = max(height // max(len(lines), 1), 18) if height else 26
    h = height or line_h * len(lines) + 6
    out = np.empty((h, width, 3), np.uint8)
    out[:] = BAND
    font = cv2.FONT_HERSHEY_SIMPLEX
    for i, text in enumerate(lines):
        scale, thick = _font_scale(width, line_h)
        while scale > 0.3:
            (tw, _th), _ = cv2.getTextSize(text, font, scale, thick)
            if tw <= width - 8:
                break
            scale *= 0.9
        y = 3 + line_h * (i + 1) - max(line_h // 4, 4)
        cv2.putText(out, text, (4, y), font, scale, TEXT, thick, cv2.LINE_AA)
    return out


def labelled_row(tiles: list[np.ndarray], headers: list[list[str]], gap: int = 4) -> np.ndarray:
    """Tiles side by side, each under its own header band (lines of text), ``gap`` pixels
    of band colour between columns. All tiles have one height."""
    lines = max(len(h) for h in headers)
    cols = []
    for i, (tile, head) in enumerate(zip(tiles, headers, strict=True)):
        top = band(tile.shape[1], head + [""] * (lines - len(head)), height=26 * lines + 6)
        col = np.concatenate([top, tile], axis=0)
        if i:
            sep = np.empty((col.shape[0], gap, 3), np.uint8)
            sep[:] = BAND
            cols.append(sep)
        cols.append(col)
    return np.concatenate(cols, axis=1)


def preview_picture(
    previews: list[tuple[str, Preview]], method: str, title: str, show_projected: bool = True
) -> np.ndarray:
    """The preview picture: a title band, then one labelled row per (row label, preview):
    white screen | uncompensated | compensated (| what the projector shows)."""
    rows = []
    name = METHOD_NAMES.get(method, method)
    for label, p in previews:
        tiles = [p.white, p.uncompensated, p.compensated]
        heads = [
            ["white screen (target)", label],
            ["uncompensated", f"dE {p.de_uncompensated:.1f} vs white"],
            [f"compensated, {name}", f"dE {p.de_compensated:.1f} vs white"],
        ]
        if show_projected:
            tiles.append(p.projected)
            heads.append(["what the projector shows", "(not what anyone sees)"])
        rows.append(labelled_row(tiles, heads))
    body = np.concatenate(rows, axis=0)
    return np.concatenate([band(body.shape[1], [title]), body], axis=0)
