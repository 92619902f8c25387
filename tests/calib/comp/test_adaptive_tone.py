"""The tone choices of Compensation: paper, global and adaptive on a real small calibration."""

from __future__ import annotations

import numpy as np
import pytest

from tests.support.calibrations import small_calibration, small_simulator
from viewcomp.calib.comp.compensation import Compensation
from viewcomp.calib.eval.adapted import adapted_delta_e
from viewcomp.calib.eval.testimages import natural_images
from viewcomp.calib.sim.simulator import make_screen, white_screen


def test_unknown_tone_is_refused() -> None:
    with pytest.raises(ValueError, match="tone must be one of"):
        Compensation(small_calibration(), "pixel", tone="local")
    with pytest.raises(ValueError, match="tone must be one of"):
        Compensation(small_calibration(), "paper", tone="adaptive")


def test_adaptive_beats_global_in_adapted_error_on_a_coloured_screen() -> None:
    cal = small_calibration(screen="red")
    sim = small_simulator()
    screen = make_screen("red", "glossy", shape=sim.shape, seed=0)
    image = natural_images(64, 32)["coffee"]
    eye = sim.rig.viewer.eye(60.0)
    ideal = sim.observe(white_screen(), image, eye)
    errs = {}
    for tone in ("global", "adaptive"):
        out, p = Compensation(cal, "pixel", tone=tone).compensate_image(image, eye)
        assert (p.field is not None) == (tone == "adaptive")
        errs[tone] = adapted_delta_e(sim.observe(screen, out, eye), ideal).de
    assert errs["adaptive"] < errs["global"]


def test_video_field_is_smoothed_and_reset_at_a_cut() -> None:
    cal = small_calibration(screen="red")
    comp = Compensation(cal, "pixel", tau=0.5, tone="adaptive")
    imgs = natural_images(64, 32)
    eye = small_simulator().rig.viewer.eye(90.0)
    from viewcomp.calib.comp.compensation import thumbnail

    first = comp(thumbnail(imgs["coffee"]), eye, 0.0).field
    again = comp(thumbnail(imgs["coffee"]), eye, 1 / 24).field
    cut = comp(thumbnail(imgs["astronaut"]), eye, 2 / 24).field
    assert first is not None and again is not None and cut is not None
    # A still shot: the local search from the same field moves it little, smoothed less.
    assert np.max(np.abs(np.log(again.gain / first.gain))) < 0.1
    assert comp.fields.raw is cut  # the cut's own field, unsmoothed


def test_a_cuts_first_stage_is_offered_early_and_replaced() -> None:
    """At a cut (video, adaptive) the caller's ``early`` gets the best uniform field before
    the node search; within a shot and for stills it is not called."""
    from viewcomp.calib.comp.compensation import FrameParams, thumbnail

    cal = small_calibration(screen="red")
    comp = Compensation(cal, "pixel", tau=0.5, tone="adaptive")
    imgs = natural_images(64, 32)
    eye = small_simulator().rig.viewer.eye(60.0)
    got: list[FrameParams] = []
    final = comp(thumbnail(imgs["coffee"]), eye, 0.0, early=got.append)
    assert len(got) == 1 and got[0].field is not None and final.field is not None
    first = got[0].field
    assert np.all(first.gain == first.gain[0, 0]) and np.all(first.offset == first.offset[0, 0])
    assert comp.fields.state is final.field  # the search's end is the shot's start
    comp(thumbnail(imgs["coffee"]), eye, 1 / 24, early=got.append)
    comp(thumbnail(imgs["coffee"]), eye, early=got.append)
    assert len(got) == 1
    comp(thumbnail(imgs["astronaut"]), eye, 2 / 24, early=got.append)
    assert len(got) == 2


def test_a_stopped_search_leaves_the_shot_as_it_was() -> None:
    """``stop`` gives a node search up (SearchStopped) before the field's state changes;
    the next call within the shot searches from the last field as before."""
    from viewcomp.calib.comp.adaptive import SearchStopped
    from viewcomp.calib.comp.compensation import thumbnail

    cal = small_calibration(screen="red")
    comp = Compensation(cal, "pixel", tau=0.5, tone="adaptive")
    imgs = natural_images(64, 32)
    eye = small_simulator().rig.viewer.eye(60.0)
    first = comp(thumbnail(imgs["coffee"]), eye, 0.0, cut=True).field
    asked = []

    def stop() -> bool:
        asked.append(1)
        return len(asked) > 3  # a cut arrives during the fourth node

    with pytest.raises(SearchStopped):
        comp(thumbnail(imgs["coffee"]), eye, 1 / 24, cut=False, stop=stop)
    assert len(asked) == 4 and comp.fields.raw is first and comp.fields.state is first
    again = comp(thumbnail(imgs["coffee"]), eye, 2 / 24, cut=False, stop=lambda: False).field
    assert again is not None and comp.fields.raw is not first
    with pytest.raises(SearchStopped):  # a whole search too: its node search asks
        comp(thumbnail(imgs["astronaut"]), eye, 3 / 24, cut=True, stop=lambda: True)


@pytest.mark.parametrize("name", ["spectralon", "satin_gold"])
def test_adaptive_keeps_what_a_bright_measured_screen_shows(materials_dir, name) -> None:
    """On measured screens that show every colour asked of them (a white reflectance
    standard, a bright satin gold), the adaptive map has nothing to trade: never 3 % worse
    than the global map in adapted error (#24's bar; measured at 64x32: equal or better, by
    up to 0.16 dE, the search keeping the global rule where it predicts less). Its knee
    once lifted every shadow that fitted and its prediction saw no loss in brightening an
    image the camera then clipped: 7-12 dE against the global map's 0.6-1.7; holding
    shadows at the lowest grey and pressing colours toward a grey on the reach's edge cost
    it 4-27 % more at 320x160."""
    from viewcomp.calib.eval.materials import material_world

    mat = material_world(materials_dir / f"{name}.npz", "hdr", (64, 32))
    assert mat.cal is not None, mat.refused
    sim = mat.sim
    eye = sim.rig.viewer.eye(90.0)
    for image in natural_images(64, 32).values():
        ideal = sim.observe(white_screen(), image, eye)
        err = {}
        for tone in ("global", "adaptive"):
            out, _ = Compensation(mat.cal, "pixel", tone=tone).compensate_image(image, eye)
            err[tone] = adapted_delta_e(sim.observe(mat.screen, out, eye), ideal).de
        assert err["adaptive"] <= 1.03 * err["global"], err


def test_prediction_sees_the_camera_clip_a_brightened_image() -> None:
    """A bright screen (M = 3 I, A = 0: it can show three times the camera's range) and an
    image reaching 0.9 of that range: doubled, it still fits the screen, but the camera
    clips everything above half of it, which no later uniform scale brings back; the
    prediction must see that (it once scaled before clipping, so a doubled image looked as
    good as the image itself)."""
    from viewcomp.calib.comp.adaptive import AdaptedPrediction
    from viewcomp.calib.model.gamut import ToneField
    from viewcomp.calib.model.reference import tone_terms

    rng = np.random.default_rng(0)
    cw = rng.uniform(0.02, 0.9, (8, 12, 3))
    m = np.broadcast_to(3.0 * np.eye(3), (8, 12, 3, 3)).copy()
    a = np.zeros((8, 12, 3))
    pred = AdaptedPrediction(*tone_terms(np.linalg.inv(m), cw, a), m, a, cw)
    same = pred(ToneField.uniform(1.0, 0.0, (3, 5)))
    doubled = pred(ToneField.uniform(2.0, 0.0, (3, 5)))
    assert same < 0.5
    assert doubled > same + 3.0
