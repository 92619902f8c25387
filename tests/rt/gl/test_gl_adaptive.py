"""The adaptive tone map in the shader against the numpy reference (calib.model.gamut),
pixel by pixel: solved per draw and from the view cache, a synthetic model with a field of
random nodes and a real calibration with the field Compensation chooses."""

from __future__ import annotations

import numpy as np
import pytest

from tests.support.calibrations import small_calibration
from tests.support.synthetic import smooth_frame, synthetic_model
from viewcomp.calib.comp.compensation import Compensation, thumbnail
from viewcomp.calib.eval.testimages import natural_images
from viewcomp.calib.model.gamut import KNEE, LUMA, ToneField, grey_range
from viewcomp.calib.model.reference import compensate, screen_at, tone_terms, white_response
from viewcomp.calib.world.eye import eye_from_angle
from viewcomp.rt.gl.compensator import Compensator

pytestmark = pytest.mark.gl

W, H = 160, 96
ANGLES = (45, 60, 90, 135)


def assert_close(gl: np.ndarray, ref: np.ndarray) -> None:
    """<= 1 level in 99.9 % of pixel-channels and <= 3 anywhere (as the global map's test)."""
    d = np.abs(gl.astype(np.int16) - ref.astype(np.int16))
    assert d.max() <= 3, f"max difference {d.max()} levels"
    assert np.mean(d > 1) <= 0.001, f"{np.mean(d > 1):.4%} of pixel-channels differ by > 1"


def random_field(seed: int, nodes: tuple[int, int] = (3, 5)) -> ToneField:
    """Nodes drawn independently (rows and columns unlike each other), so that a shader that
    read them transposed, mirrored or shifted by a node would not match."""
    rng = np.random.default_rng(seed)
    return ToneField(rng.uniform(0.3, 2.0, nodes), rng.uniform(-0.06, 0.06, nodes))


def knee_share(model, frame: np.ndarray, eye: np.ndarray, field: ToneField) -> float:
    """The share of pixels whose target luminance lies below their grey range or in its top
    KNEE (where the soft clip holds or bends), computed here without gamut.soft_light."""
    from viewcomp.calib.model.gamut import field_at

    cw = white_response(model, frame)
    m, a = screen_at(model, eye)
    _, v, c = tone_terms(np.linalg.inv(m.astype(np.float64)), cw, a)
    lo, hi = grey_range(v, c)
    g, o = field_at(field, model.shape)
    lum = g * (cw @ LUMA) + o
    span = hi - lo
    return float(np.mean((lum > hi - KNEE * span) | (lum < lo)))


@pytest.fixture(scope="module")
def model():
    return synthetic_model("pixel", W, H, seed=3)


@pytest.mark.parametrize("cached", [False, True], ids=["solve", "cached"])
@pytest.mark.parametrize("angle", ANGLES)
def test_adaptive_matches_reference(gl_ctx, model, angle: float, cached: bool) -> None:
    frame = smooth_frame(W, H, seed=5)
    field = random_field(angle)
    eye = eye_from_angle(angle, 0.5, 0.035)
    with Compensator(model, gl_ctx, view_cache=cached, view_hold=0, view_steps=1) as comp:
        comp.set_eye(*eye)
        comp.set_field(field)
        out = comp.render(frame)
        assert comp.last_path == ("adaptive-cached" if cached else "adaptive")
        ref = compensate(model, frame, eye, 1.0, 0.0, field=field)
        assert_close(out, ref)
        # The field matters here: the same pixels under its mean gain and offset differ.
        flat = ToneField.uniform(float(field.gain.mean()), float(field.offset.mean()), (3, 5))
        assert (
            np.abs(compensate(model, frame, eye, 1.0, 0.0, field=flat) - ref.astype(int)).max() > 8
        )
        # and the soft clip is exercised, not only the middle of each pixel's range.
        assert knee_share(model, frame, eye, field) > 0.05
        # None goes back to the global map.
        comp.set_field(None)
        comp.set_tone(0.6, 0.01)
        assert_close(comp.render(frame), compensate(model, frame, eye, 0.6, 0.01))
        assert comp.last_path == ("cached" if cached else "solve")


def test_other_node_counts_compile_their_own_program(gl_ctx, model) -> None:
    frame = smooth_frame(W, H, seed=7)
    eye = eye_from_angle(70, 0.5, 0.035)
    with Compensator(model, gl_ctx, view_cache=False) as comp:
        comp.set_eye(*eye)
        for nodes in ((1, 1), (2, 3), (4, 6)):
            field = random_field(sum(nodes), nodes)
            comp.set_field(field)
            assert_close(comp.render(frame), compensate(model, frame, eye, 1.0, 0.0, field=field))


@pytest.mark.parametrize("angle", (60, 125))
def test_adaptive_on_a_real_calibration(gl_ctx, angle: float) -> None:
    """The field Compensation(tone="adaptive") chooses for a photograph on the red screen."""
    comp = Compensation(small_calibration(screen="red"), "pixel", tone="adaptive")
    frame = natural_images(64, 32)["coffee"]
    eye = eye_from_angle(angle, 0.5, 0.035)
    p = comp(thumbnail(frame), eye)
    assert p.field is not None
    ref = compensate(p.model, frame, eye, p.alpha, p.beta, field=p.field)
    for cached in (False, True):
        with Compensator(p.model, gl_ctx, view_cache=cached, view_hold=0, view_steps=1) as gl:
            gl.set_eye(*eye)
            gl.set_field(p.field)
            assert_close(gl.render(frame), ref)


@pytest.mark.parametrize("cached", [False, True], ids=["solve", "cached"])
def test_hue_weight_mixes_the_soft_clip_with_the_per_channel_clip(gl_ctx, model, cached) -> None:
    """A field's hue weight between 0 and 1 draws as the reference does, and a uniform field
    of weight 0 is the global tone map (alpha, beta) exactly: the reference's global map
    (reference.compensate without a field) is the check, not the adaptive code."""
    frame = smooth_frame(W, H, seed=9)
    eye = eye_from_angle(75, 0.5, 0.035)
    field = random_field(11)
    mixed = ToneField(field.gain, field.offset, 0.35)
    glob = ToneField.uniform(0.8, 0.02, (3, 5), hue=0.0)
    with Compensator(model, gl_ctx, view_cache=cached, view_hold=0, view_steps=1) as comp:
        comp.set_eye(*eye)
        comp.set_field(mixed)
        ref = compensate(model, frame, eye, 1.0, 0.0, field=mixed)
        assert_close(comp.render(frame), ref)
        # the weight matters here: the same nodes at weight 1 differ
        whole = compensate(model, frame, eye, 1.0, 0.0, field=field)
        assert np.abs(whole.astype(int) - ref).max() > 8
        comp.set_field(glob)
        ref0 = compensate(model, frame, eye, 1.0, 0.0, field=glob)
        assert np.array_equal(ref0, compensate(model, frame, eye, 0.8, 0.02))
        assert_close(comp.render(frame), ref0)


def test_field_checks(gl_ctx) -> None:
    paper = synthetic_model("paper", 16, 8, seed=1)
    with Compensator(paper, gl_ctx) as comp, pytest.raises(ValueError, match="pixel method"):
        comp.set_field(random_field(0))
    with Compensator(synthetic_model("pixel", 16, 8, seed=1), gl_ctx) as comp:
        bad = ToneField(np.full((3, 5), np.nan), np.zeros((3, 5)))
        with pytest.raises(ValueError, match="NaN"):
            comp.set_field(bad)
        for hue in (-0.1, 1.5, float("nan")):
            with pytest.raises(ValueError, match="hue weight"):
                comp.set_field(ToneField.uniform(1.0, 0.0, (3, 5), hue))
