"""Several viewers at once (docs/MODEL.md section 6): the SPEC, the least squares against its
closed form, one viewer equal to one eye, the shader against the numpy reference."""

from __future__ import annotations

import numpy as np
import pytest

from tests.support.synthetic import make_compensation, smooth_frame, synthetic_model
from viewcomp.calib.comp.compensation import thumbnail
from viewcomp.calib.comp.tonemap import choose_predicted_tone_map
from viewcomp.calib.model.reference import (
    audience_solve,
    compensate,
    screen_at,
    target_to_projector,
    tone_terms,
)
from viewcomp.calib.world.audience import (
    MAX_VIEWERS,
    Audience,
    AudienceError,
    parse_audience,
    zone,
    zone_angles,
)
from viewcomp.calib.world.eye import eye_from_angle

W, H = 48, 32
D, HT = 0.5, 0.035


@pytest.fixture(scope="module")
def model():
    return synthetic_model("pixel", W, H, seed=3)


@pytest.fixture(scope="module")
def target():
    rng = np.random.default_rng(1)
    return rng.uniform(0.05, 0.5, (H, W, 3)).astype(np.float32)


# ----------------------------------------------------------------------- the SPEC
def test_zone_spreads_viewers_evenly():
    a = parse_audience("60:120", D, HT)
    assert len(a) == 7
    np.testing.assert_allclose(zone_angles(a), np.arange(60, 121, 10), atol=1e-9)
    np.testing.assert_allclose(a.weights, np.full(7, 1 / 7))
    np.testing.assert_allclose(a.eyes[3], eye_from_angle(90, D, HT), atol=1e-12)
    assert len(parse_audience("45:135:13", D, HT)) == 13


def test_angles_eyes_and_weights():
    a = parse_audience("90@2;60 120", D, HT)
    np.testing.assert_allclose(a.weights, [0.5, 0.25, 0.25])
    np.testing.assert_allclose(zone_angles(a), [90, 60, 120], atol=1e-9)
    b = parse_audience("0.2,0.03,0.5;-0.2,0.03,0.5", D, HT)
    np.testing.assert_allclose(b.eyes, [[0.2, 0.03, 0.5], [-0.2, 0.03, 0.5]])
    z = parse_audience("60:120@3;90", D, HT)  # a zone's weight is shared by its viewers
    np.testing.assert_allclose(z.weights[:7].sum() / z.weights[7], 3.0)


@pytest.mark.parametrize(
    ("spec", "match"),
    [
        ("", "empty"),
        ("60,90,120", "separate them with ';'"),
        ("60:120:0", "1 to 16"),
        ("60:120:2.5", "whole"),
        ("0:120", r"\[1, 179\]"),
        ("abc", "not a number"),
        ("90@0", "positive"),
        ("0.1,0.0,-0.5", "in front of the screen"),
        ("1:179:17", "1 to 16"),
        (";".join(["90"] * (MAX_VIEWERS + 1)), "more than 16"),
        ("60:120:nan", "finite"),
    ],
)
def test_bad_specs_name_the_item(spec, match):
    with pytest.raises(AudienceError, match=match):
        parse_audience(spec, D, HT)


def test_audience_checks_its_arrays():
    with pytest.raises(AudienceError, match="weight"):
        Audience(np.array([[0, 0, 1.0], [0.1, 0, 1.0]]), np.array([1.0, -1.0]))
    with pytest.raises(AudienceError, match="eyes"):
        Audience(np.ones((2, 2)), np.ones(2))


# ----------------------------------------------------------------------- the math
def test_least_squares_matches_its_closed_form(model, target):
    """The normal equations' solve equals the least squares of the stacked sqrt(w_k) M_k
    (float64 lstsq), for an uneven audience."""
    aud = Audience(
        np.stack([eye_from_angle(a, D, HT) for a in (50, 80, 95, 130)]), np.array([1, 2, 3, 1.0])
    )
    y = target_to_projector(model, target, aud).astype(np.float64)
    screens = [screen_at(model, e) for e in aud.eyes]
    a = np.concatenate(
        [np.sqrt(w) * m for (m, _), w in zip(screens, aud.weights, strict=True)], axis=-2
    )
    b = np.concatenate(
        [np.sqrt(w) * (target - c) for (_, c), w in zip(screens, aud.weights, strict=True)], -1
    )
    want = np.linalg.lstsq(a.reshape(-1, 12, 3)[0].astype(np.float64), b.reshape(-1, 12)[0])[0]
    np.testing.assert_allclose(y.reshape(-1, 3)[0], want, rtol=0, atol=1e-5)
    ref = np.stack(
        [np.linalg.lstsq(ai.astype(np.float64), bi, rcond=None)[0]
         for ai, bi in zip(a.reshape(-1, 12, 3), b.reshape(-1, 12), strict=True)]
    ).reshape(H, W, 3)  # fmt: skip
    scale = np.abs(ref).max()
    assert np.abs(y - ref).max() <= 1e-5 * max(scale, 1.0)


def test_least_squares_beats_every_single_eye(model, target):
    """No other light has a smaller weighted residual: in particular not the exact solve for
    any one viewer (the audience optimum is the optimum)."""
    aud = zone(60, 120, 5, D, HT)
    screens = [screen_at(model, e) for e in aud.eyes]

    def cost(y):
        r = [np.einsum("hwij,hwj->hwi", m, y) + c - target for m, c in screens]
        return sum(
            w * (ri.astype(np.float64) ** 2).sum(-1) for w, ri in zip(aud.weights, r, strict=True)
        )

    best = cost(target_to_projector(model, target, aud))
    for e in aud.eyes:
        other = cost(target_to_projector(model, target, e))
        assert np.all(best <= other + 1e-9)
    assert np.mean(best < cost(target_to_projector(model, target, aud.eyes[2])) - 1e-9) > 0.5


def test_one_viewer_is_the_eye_exactly(model, target):
    """An audience of one takes the one-eye solve: identical numbers, not merely close."""
    e = eye_from_angle(70, D, HT)
    one = Audience(e[None], np.ones(1))
    y1 = target_to_projector(model, target, e)
    y2 = target_to_projector(model, target, one)
    assert np.abs(y1 - y2).max() <= 1e-6
    frame = smooth_frame(W, H, seed=5)
    assert np.array_equal(
        compensate(model, frame, one, 0.6, 0.01), compensate(model, frame, e, 0.6, 0.01)
    )


def test_normal_equations_of_a_repeated_eye_equal_the_solve(model, target):
    """The normal-equation path (two viewers at one eye) equals the direct solve of that eye
    up to float32 rounding: P = (M^T M)^-1 M^T = M^-1."""
    e = eye_from_angle(110, D, HT)
    twice = Audience(np.stack([e, e]), np.array([0.3, 0.7]))
    y1 = target_to_projector(model, target, e)
    y2 = target_to_projector(model, target, twice)
    assert np.abs(y1 - y2).max() <= 1e-5
    p, d = audience_solve(model, twice)
    m, a = screen_at(model, e)
    np.testing.assert_allclose(p, np.linalg.inv(m), atol=1e-4)
    np.testing.assert_allclose(d, np.einsum("hwij,hwj->hwi", np.linalg.inv(m), a), atol=1e-5)


def test_tone_map_of_a_one_viewer_audience_is_the_eye_s():
    """choose_predicted_tone_map's audience form with one viewer predicts what its one-eye
    form predicts (M y + A = T exactly there), so it picks the same tone map."""
    comp = make_compensation("pixel", 64, 32)
    frame = smooth_frame(64, 32, seed=2)
    thumb = thumbnail(frame)
    e = eye_from_angle(65, D, HT)
    small = comp._small_model(comp.base_model(), thumb.shape[:2])
    from viewcomp.calib.model.reference import white_response

    cw = white_response(small, thumb).astype(np.float64)
    m, a = (x.astype(np.float64) for x in screen_at(small, e))
    u, v, c = tone_terms(np.linalg.inv(m), cw, a)
    plain = choose_predicted_tone_map(u, v, c, m, cw, 0.0, 1.0)
    as_audience = choose_predicted_tone_map(
        u, v, c, m, cw, 0.0, 1.0, None, (m[None], a[None], np.ones(1))
    )
    assert (plain.alpha, plain.beta) == pytest.approx(
        (as_audience.alpha, as_audience.beta), abs=1e-9
    )
    assert plain.cost == pytest.approx(as_audience.cost, rel=1e-6)


def test_compensation_takes_an_audience():
    """Compensation: an audience's tone map and output differ from the centre eye's, the
    paper's method refuses several viewers."""
    comp = make_compensation("pixel", 64, 32)
    frame = smooth_frame(64, 32, seed=2)
    aud = zone(45, 135, 5, D, HT)
    out_a, p_a = comp.compensate_image(frame, aud)
    out_e, _ = comp.compensate_image(frame, aud.eyes[2])
    assert out_a.shape == frame.shape and not np.array_equal(out_a, out_e)
    assert 0.2 <= p_a.alpha <= 1.5
    with pytest.raises(ValueError, match="pixel method"):
        make_compensation("paper", 64, 32)(thumbnail(frame), aud)


# ----------------------------------------------------------------------- the shader
ALPHA, BETA = 0.55, 0.02


def _assert_close(gl: np.ndarray, ref: np.ndarray) -> None:
    d = np.abs(gl.astype(np.int16) - ref.astype(np.int16))
    assert d.max() <= 3, f"max difference {d.max()} levels"
    assert np.mean(d > 1) <= 0.001, f"{np.mean(d > 1):.4%} of pixel-channels differ by > 1"


@pytest.mark.gl
@pytest.mark.parametrize("cached", [False, True], ids=["solve", "cached"])
@pytest.mark.parametrize("spec", ["60:120", "30;150@2", "45:90:4"])
def test_gl_audience_matches_reference(gl_ctx, model, cached, spec):
    from viewcomp.rt.gl.compensator import Compensator

    aud = parse_audience(spec, D, HT)
    frame = smooth_frame(W, H, seed=5)
    ref = compensate(model, frame, aud, ALPHA, BETA)
    with Compensator(model, gl_ctx, view_cache=cached, view_hold=0, view_steps=2) as comp:
        comp.set_tone(ALPHA, BETA)
        comp.set_audience(aud)
        out = comp.render(frame)
        if cached:  # two bands: the first draw solves, the second reads the cache
            assert comp.last_path == "audience"
            out = comp.render(frame)
        _assert_close(out, ref)
        assert comp.last_path == ("cached" if cached else "audience")
        np.testing.assert_allclose(comp.eye, aud.centre, atol=1e-6)


@pytest.mark.gl
def test_gl_audience_on_a_real_calibration(gl_ctx):
    """Frame parameters from Compensation for an audience (model, tone map) into both
    backends, on a simulated glossy magenta screen."""
    from viewcomp.rt.gl.compensator import Compensator

    comp = make_compensation("pixel", 64, 32)
    frame = smooth_frame(64, 32, seed=6)
    aud = zone(60, 120, 7, D, HT)
    p = comp(thumbnail(frame), aud)
    ref = compensate(p.model, frame, aud, p.alpha, p.beta)
    for cached in (False, True):
        with Compensator(p.model, gl_ctx, view_cache=cached, view_hold=0, view_steps=1) as gl:
            gl.set_audience(aud)
            gl.set_tone(p.alpha, p.beta)
            _assert_close(gl.render(frame), ref)


@pytest.mark.gl
@pytest.mark.parametrize("cached", [False, True], ids=["solve", "cached"])
def test_gl_one_viewer_is_the_eye_bit_for_bit(gl_ctx, model, cached):
    from viewcomp.rt.gl.compensator import Compensator

    frame = smooth_frame(W, H, seed=7)
    e = eye_from_angle(75, D, HT)
    with Compensator(model, gl_ctx, view_cache=cached, view_hold=0, view_steps=1) as comp:
        comp.set_tone(ALPHA, BETA)
        comp.set_audience(parse_audience("75", D, HT))
        a = comp.render(frame).copy()
        path = comp.last_path
        comp.set_audience(zone(60, 120, 3, D, HT))  # something else in between
        comp.render(frame)
        comp.set_eye(*e)
        b = comp.render(frame)
        assert path == comp.last_path == ("cached" if cached else "solve")
    assert np.array_equal(a, b)


@pytest.mark.gl
def test_held_audience_draws_from_the_view_cache(gl_ctx, model):
    """A held audience is drawn by the very program a held eye uses (the cache holds the
    combined solve), so its per-draw cost is the held eye's (bench/bench_audience.py)."""
    from viewcomp.rt.gl.compensator import _CACHED, Compensator

    frame = smooth_frame(W, H, seed=8)
    with Compensator(model, gl_ctx, view_hold=1, view_steps=1) as comp:
        comp.set_audience(zone(60, 120, 7, D, HT))
        comp.render(frame)
        assert comp.last_path == "audience"  # the first draw at a new audience solves
        comp.render(frame)
        assert comp.last_path == "cached"
        programs = set(comp._programs)
        comp.set_eye(*eye_from_angle(80, D, HT))
        comp.render(frame)
        comp.render(frame)
        assert comp.last_path == "cached"
        cached = {k for k in comp._programs if k[0] == _CACHED}
        assert len(cached) == 1 and cached <= programs


# ----------------------------------------------------------------------- the commands
@pytest.fixture(scope="module")
def bundle(tmp_path_factory):
    from viewcomp.cli import main

    d = tmp_path_factory.mktemp("audience")
    assert main(["simulate", str(d / "caps"), "--size", "64x32", "--screen", "magenta"]) == 0
    assert main(["calibrate", str(d / "caps"), "-o", str(d / "m.vcb")]) == 0
    return d / "m.vcb"


@pytest.mark.gl
@pytest.mark.parametrize("backend", ["gl", "cpu"])
def test_render_one_viewer_audience_equals_the_angle(bundle, tmp_path, backend):
    """`render --audience 75` writes the very image `render --angle 75` does; a zone writes
    another."""
    from viewcomp.calib.io.imageio import read_image, write_png
    from viewcomp.cli import main

    src = tmp_path / "in.png"
    write_png(src, smooth_frame(64, 32, seed=4))
    outs = {}
    for name, where in (("angle", ["--angle", "75"]), ("one", ["--audience", "75"]),
                        ("zone", ["--audience", "60:120"])):  # fmt: skip
        out = tmp_path / f"{name}.png"
        assert main(["render", str(bundle), str(src), "-o", str(out), "--backend", backend,
                     "--quiet", *where]) == 0  # fmt: skip
        outs[name] = read_image(out)
    assert np.array_equal(outs["angle"], outs["one"])
    assert not np.array_equal(outs["angle"], outs["zone"])


def test_render_refuses_a_bad_audience_before_work(bundle, tmp_path, capsys):
    from viewcomp.calib.io.imageio import write_png
    from viewcomp.cli import main

    src = tmp_path / "in.png"
    write_png(src, smooth_frame(64, 32, seed=4))
    out = tmp_path / "out.png"
    code = main(["render", str(bundle), str(src), "-o", str(out), "--audience", "60,90,120"])
    assert code == 2 and not out.exists()
    assert "separate them with ';'" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:  # a usage error: argparse's exit
        main(["render", str(bundle), str(src), "-o", str(out), "--audience", "60:120",
              "--method", "paper"])  # fmt: skip
    assert exc.value.code == 2 and "--method pixel" in capsys.readouterr().err


def test_eyes_lines_and_osc_make_an_audience():
    from viewcomp.rt.play.live import (
        EYES_ADDRESS,
        SetAudience,
        SetEye,
        parse_line,
        parse_osc_message,
    )

    cmd = parse_line("eyes 0.1 0.03 0.5 -0.2 0.03 0.8")
    assert cmd == SetAudience(((0.1, 0.03, 0.5), (-0.2, 0.03, 0.8)))
    assert parse_line("eyes 0.1 0.03 0.5") == SetEye((0.1, 0.03, 0.5))
    assert parse_osc_message(EYES_ADDRESS, [0.1, 0.0, 0.5, 0.2, 0.0, 0.5]) == SetAudience(
        ((0.1, 0.0, 0.5), (0.2, 0.0, 0.5))
    )


def test_hub_publisher_sends_every_face():
    from viewcomp.rt.play.live import InputHub, SetAudience
    from viewcomp.rt.track.publish import HubPublisher

    hub = InputHub()
    eyes = np.array([[0.1, 0.03, 1.0], [-0.3, 0.03, 2.0]])
    assert HubPublisher(hub, all_faces=True).publish(eyes)
    assert HubPublisher(hub).publish(eyes)
    got = [r.command for r in hub.drain()]
    assert isinstance(got[0], SetAudience) and len(got[0].eyes) == 2
    assert got[1].eye == (0.1, 0.03, 1.0)


@pytest.mark.gl
def test_live_renderer_follows_an_audience(gl_ctx):
    """LiveRenderer: an audience from the start and from SetAudience draws what the
    Compensator draws for it; an eye command ends it."""
    from tests.support.calibrations import small_calibration
    from viewcomp.rt.play.embed import LiveRenderer
    from viewcomp.rt.play.live import SetAngle, SetAudience

    cal = small_calibration(64, 32, screen="magenta")
    frame = smooth_frame(64, 32, seed=3)
    aud = zone(60, 120, 5, cal.rig.viewer.distance, cal.rig.viewer.height)
    with LiveRenderer(cal, gl_ctx, audience=aud, async_tone=False, tone_tau=None) as live:
        live.prepare(frame)
        assert live.last.audience is aud and live.compensator.audience is not None
        np.testing.assert_allclose(live.eye, aud.centre)
        live.apply(SetAudience(tuple(tuple(e) for e in aud.eyes[:2])))
        live.prepare(frame)
        assert len(live.last.audience) == 2
        live.apply(SetAngle(70.0), smooth=False)
        live.prepare(frame)
        assert live.last.audience is None and live.compensator.audience is None
