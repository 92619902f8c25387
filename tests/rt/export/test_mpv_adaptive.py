"""`viewcomp export-mpv --tone adaptive`: one field per export, chosen for --tone-from as
`render` chooses it, and the exported hook run through this project's GL path against the
numpy reference of that field."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from tests.support.calibrations import small_calibration
from tests.support.mpv_hooks import run_hook, sections, textures
from viewcomp.calib.comp.compensation import Compensation, thumbnail
from viewcomp.calib.eval.testimages import natural_images
from viewcomp.calib.model.reference import compensate
from viewcomp.rt.export.mpv import ExportError, export_mpv_shader

pytestmark = pytest.mark.usefixtures("session_gl_current")

W, H = 64, 32


@pytest.fixture(scope="module")
def cal() -> Any:
    return small_calibration(W, H, screen="red")


@pytest.fixture(scope="module")
def image() -> np.ndarray:
    return natural_images(W, H)["coffee"]


def test_structure(cal: Any, image: np.ndarray) -> None:
    text, info = export_mpv_shader(cal, angle=60.0, tone_sample=image, tone_mode="adaptive")
    hook = sections(text)[0][0]
    assert hook["BIND"] == ["HOOKED", *(f"VC_ROW{k}" for k in range(6)), "VC_LUT"]
    assert all(textures(text)[f"VC_ROW{k}"].shape == (H, W, 4) for k in range(6))
    assert info.tone == "adaptive" and "Tone map: adaptive, a 3x5-node field" in text
    assert export_mpv_shader(cal, angle=60.0, tone_sample=image)[1].tone == "global"


@pytest.mark.gl
@pytest.mark.parametrize("precision", [16, 32])
@pytest.mark.parametrize("angle", [60.0, 125.0])
def test_exported_adaptive_hook_matches_the_reference(
    gl_ctx: Any, cal: Any, image: np.ndarray, angle: float, precision: int
) -> None:
    text, _ = export_mpv_shader(cal, angle=angle, tone_sample=image, tone_mode="adaptive",
                                precision=precision)  # fmt: skip
    eye = cal.eye(angle=angle)
    p = Compensation(cal, "pixel", tone="adaptive")(thumbnail(image), eye)
    assert p.field is not None
    ref = compensate(p.model, image, eye, p.alpha, p.beta, field=p.field)
    other = compensate(p.model, image, eye, p.alpha, p.beta)  # the global map: not this
    assert np.abs(ref.astype(int) - other).mean() > 1
    got = run_hook(gl_ctx, text, image)
    d = np.abs(got.astype(int) - ref)
    print(f"adaptive export ({precision} bits, {angle} deg): max {d.max()}, "
          f"{(d > 1).sum()} of {d.size} over 1")  # fmt: skip
    assert d.max() <= 3 and np.mean(d > 1) <= 0.001


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"param": True}, "drop --param"),
        ({"tone": (0.5, 0.0)}, "--tone-from"),
        ({"precision": 8}, "--precision 16 or 32"),
        ({"method": "paper"}, "needs --method pixel"),
    ],
)
def test_adaptive_refusals(cal: Any, kwargs: dict, match: str) -> None:
    with pytest.raises(ExportError, match=match):
        export_mpv_shader(cal, angle=60.0, tone_mode="adaptive", **kwargs)
