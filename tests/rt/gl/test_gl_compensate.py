"""The shader against the numpy reference (docs/RUNTIME.md): synthetic and real models."""

from __future__ import annotations

import os
from dataclasses import replace

import moderngl
import numpy as np
import pytest

from tests.support.synthetic import (
    make_compensation,
    smooth_frame,
    synthetic_model,
    uniform_frame,
)
from viewcomp.calib.model.reference import compensate
from viewcomp.calib.world.eye import eye_from_angle
from viewcomp.rt.gl.compensator import Compensator, pixel_texels
from viewcomp.rt.gl.context import live_gl_objects
from viewcomp.rt.media.frames import Planes, rgb_to_yuv420p, yuv420p_to_rgb

pytestmark = pytest.mark.gl

W, H = 160, 96
ANGLES = (45, 60, 90, 120, 135)
ALPHA, BETA = 0.55, 0.02


def assert_close(gl: np.ndarray, ref: np.ndarray) -> None:
    """<= 1 level in 99.9 % of pixel-channels and <= 3 anywhere."""
    d = np.abs(gl.astype(np.int16) - ref.astype(np.int16))
    assert d.max() <= 3, f"max difference {d.max()} levels"
    assert np.mean(d > 1) <= 0.001, f"{np.mean(d > 1):.4%} of pixel-channels differ by > 1"


# (method, path): "solve" solves per draw, "cached" draws from the view cache (built on the
# first draw at an eye: view_hold=0).
VARIANTS = [("pixel", "solve"), ("pixel", "cached"), ("paper", "paper")]


@pytest.fixture(scope="module", params=VARIANTS, ids=["-".join(v) for v in VARIANTS])
def comp_and_model(request, gl_ctx):
    method, path = request.param
    model = synthetic_model(method, W, H, seed=3)
    cached = path == "cached"
    with Compensator(model, gl_ctx, view_cache=cached, view_hold=0, view_steps=1) as comp:
        comp.expected_path = path
        yield comp, model


@pytest.mark.parametrize("angle", ANGLES)
@pytest.mark.parametrize("kind", ["smooth", "uniform"])
def test_gl_matches_reference(comp_and_model, angle: float, kind: str) -> None:
    comp, model = comp_and_model
    frame = smooth_frame(W, H, seed=5) if kind == "smooth" else uniform_frame(W, H)
    eye = eye_from_angle(angle, 0.5, 0.035)
    comp.identity = False
    comp.set_eye(*eye)
    comp.set_tone(ALPHA, BETA)
    ref = compensate(model, frame, eye, ALPHA, BETA)
    assert_close(comp.render(frame), ref)
    assert comp.last_path == comp.expected_path
    assert ref.std() > 0 or kind == "uniform"


@pytest.fixture(scope="module", params=["pixel", "paper"])
def real(request):
    """A real Compensation (simulated magenta glossy screen, 64x32) and a natural frame."""
    comp = make_compensation(request.param, 64, 32)
    return comp


@pytest.mark.parametrize("angle", ANGLES)
@pytest.mark.parametrize("kind", ["smooth", "uniform"])
@pytest.mark.parametrize("cached", [False, True], ids=["solve", "cached"])
def test_gl_matches_reference_on_a_real_calibration(gl_ctx, real, angle, kind, cached) -> None:
    """Frame parameters from Compensation (model at the eye, tone map) into both backends."""
    from viewcomp.calib.comp.compensation import thumbnail

    h, w = real.shape
    frame = smooth_frame(w, h, seed=6) if kind == "smooth" else uniform_frame(w, h)
    eye = eye_from_angle(angle, 0.5, 0.035)
    try:
        p = real(thumbnail(frame), eye)
    except Exception as exc:  # the CPU side's problem, not the shader's: see the message
        if type(exc).__name__ == "FitError":
            pytest.xfail(f"Compensation({real.method}) fails at {angle} degrees: {exc}")
        raise
    ref = compensate(p.model, frame, eye, p.alpha, p.beta)
    with Compensator(p.model, gl_ctx, view_cache=cached, view_hold=0, view_steps=1) as comp:
        comp.set_eye(*eye)
        comp.set_tone(p.alpha, p.beta)
        assert_close(comp.render(frame), ref)
        if real.method == "pixel":
            assert comp.last_path == ("cached" if cached else "solve")


def test_identity_is_bit_exact(comp_and_model) -> None:
    comp, _ = comp_and_model
    frame = np.random.default_rng(0).integers(0, 256, (H, W, 3), dtype=np.uint8)
    comp.identity = True
    try:
        np.testing.assert_array_equal(comp.render(frame), frame)
    finally:
        comp.identity = False


def test_video_planes_match_reference(comp_and_model) -> None:
    """Planes converted in the shader give what the CPU backend computes from them."""
    comp, model = comp_and_model
    planes = rgb_to_yuv420p(smooth_frame(W, H, seed=9), "bt709", "limited")
    eye = eye_from_angle(70, 0.5, 0.035)
    comp.set_eye(*eye)
    comp.set_tone(ALPHA, BETA)
    ref = compensate(model, yuv420p_to_rgb(planes), eye, ALPHA, BETA)
    assert_close(comp.render_planes(planes), ref)


def test_pixel_texels_layout() -> None:
    """The maps' 8 texels per pixel hold the model's arrays as compensate_core.glsl reads
    them, and the camera's lobe that the reference uses."""
    from viewcomp.calib.model.reference import lobe_change

    model = synthetic_model("pixel", 40, 24, seed=2)
    t = pixel_texels(model)
    assert t.shape == (24, 40, 8, 4) and t.dtype == np.float32
    np.testing.assert_array_equal(t[:, :, 0:3, :3], model.Ww)
    np.testing.assert_array_equal(t[:, :, 0:3, 3], model.Aw)
    np.testing.assert_array_equal(t[:, :, 3:6, :3], model.Wc)
    np.testing.assert_array_equal(t[:, :, 3:6, 3], model.Ac)
    np.testing.assert_array_equal(t[:, :, 6, :3], model.refl)
    np.testing.assert_array_equal(t[:, :, 7, :2], model.pos[..., :2])
    np.testing.assert_array_equal(t[:, :, 6, 3], model.cam_lobe[..., 0])
    np.testing.assert_array_equal(t[:, :, 7, 2:], model.cam_lobe[..., 1:])
    # At the camera's own position the lobe does not change.
    assert np.abs(lobe_change(model, model.cam_eye)).max() == 0.0
    assert 0.0 < model.cam_lobe.max() <= 0.35


@pytest.mark.parametrize(
    ("change", "match"),
    [
        (lambda m: replace(m, Ww=m.Ww[..., :2]), r"Ww must be \(16, 32, 3, 3\), got .*3, 2\)"),
        (lambda m: replace(m, Ac=m.Ac[:8]), r"Ac must be \(16, 32, 3\), got \(8, 32, 3\)"),
        (lambda m: replace(m, Wc=None), r"pixel method needs Ww, Wc"),
        (lambda m: replace(m, pos=m.pos[:, :, :2]), r"must be \(16, 32, 3\)|refl must be"),
        (lambda m: replace(m, refl=m.refl[0]), r"refl must be \(H, W, 3\), got \(32, 3\)"),
        (lambda m: replace(m, inv_lut=m.inv_lut[:, 0]), r"inv_lut must be \(N, 3\)"),
        (lambda m: replace(m, fwd_lut=m.fwd_lut[:100]), r"fwd_lut must be \(256, 3\)"),
        (lambda m: replace(m, lobe=np.zeros((9, 2), np.float32)), r"lobe must be \(n, 3\)"),
        (lambda m: replace(m, lobe_black=np.zeros(2, np.float32)), r"lobe_black must be \(3,\)"),
        (lambda m: replace(m, Wc=np.where(m.Wc > 0.5, np.nan, m.Wc)), r"Wc holds NaN"),
        (lambda m: replace(m, lobe=np.full((9, 3), np.inf, np.float32)), r"lobe holds|not finite"),
        (lambda m: replace(m, pos=m.pos + np.float32(0.01)), r"screen plane z = 0"),
        (lambda m: replace(m, method="magic"), r"model.method must be one of"),
    ],
)
def test_corrupt_model_is_a_clear_value_error(gl_ctx, change, match) -> None:
    model = change(synthetic_model("pixel", 32, 16))
    probe0 = live_gl_objects(gl_ctx)
    with pytest.raises(ValueError, match=match):
        Compensator(model, gl_ctx)
    assert live_gl_objects(gl_ctx) == probe0  # nothing left behind by the failed set-up


def test_corrupt_paper_model_is_a_clear_value_error(gl_ctx) -> None:
    model = synthetic_model("paper", 32, 16)
    with pytest.raises(ValueError, match=r"paper method needs model.Wc_inv"):
        Compensator(replace(model, Wc_inv=None), gl_ctx)
    with pytest.raises(ValueError, match=r"Wc_inv must be \(3, 3\), got \(2, 3\)"):
        Compensator(replace(model, Wc_inv=model.Wc_inv[:2]), gl_ctx)
    with pytest.raises(ValueError, match=r"model must be a RuntimeModel"):
        Compensator({"method": "paper"}, gl_ctx)  # type: ignore[arg-type]


def test_paper_update_model(gl_ctx) -> None:
    model = synthetic_model("paper", W, H)
    frame = smooth_frame(W, H, seed=2)
    eye = eye_from_angle(60, 0.5, 0.035)
    with Compensator(model, gl_ctx) as comp:
        comp.set_eye(*eye)
        comp.set_tone(ALPHA, BETA)
        before = comp.render(frame)
        model.Wc_inv = (model.Wc_inv * 0.8).astype(np.float32)
        model.inv_lut = np.sqrt(model.inv_lut).astype(np.float32)
        comp.update_model(model.Wc_inv, model.inv_lut, model.inv_lo, model.inv_hi)
        after = comp.render(frame)
        assert not np.array_equal(before, after)
        assert_close(after, compensate(model, frame, eye, ALPHA, BETA))
        model.inv_lo = np.array([0.01, 0.0, -0.01], np.float32)
        model.inv_hi = (model.inv_hi * 1.1).astype(np.float32)
        comp.update_model(inv_lo=model.inv_lo, inv_hi=model.inv_hi)
        assert_close(comp.render(frame), compensate(model, frame, eye, ALPHA, BETA))
        with pytest.raises(ValueError, match="inv_lut must be"):
            comp.update_model(inv_lut=np.zeros((7, 3), np.float32))


@pytest.mark.parametrize("colorspace", ["bt601", "bt709"])
@pytest.mark.parametrize("color_range", ["limited", "full"])
def test_yuv_conversion(gl_ctx, colorspace: str, color_range: str) -> None:
    """GL == numpy fixed point exactly; numpy fixed point == float BT.601/709 within 1 level."""
    rng = np.random.default_rng(1)
    h, w = 37, 51  # odd sizes: chroma is ceil(size / 2)
    planes = Planes(
        rng.integers(0, 256, (h, w), dtype=np.uint8),
        rng.integers(0, 256, ((h + 1) // 2, (w + 1) // 2), dtype=np.uint8),
        rng.integers(0, 256, ((h + 1) // 2, (w + 1) // 2), dtype=np.uint8),
        colorspace,  # type: ignore[arg-type]
        color_range,  # type: ignore[arg-type]
    )
    cpu = yuv420p_to_rgb(planes)
    model = synthetic_model("paper", w, h)
    with Compensator(model, gl_ctx) as comp:
        comp.identity = True
        np.testing.assert_array_equal(comp.render_planes(planes), cpu)

    # Float reference on chroma upsampled with the same weights.
    kr, kb = {"bt601": (0.299, 0.114), "bt709": (0.2126, 0.0722)}[colorspace]
    kg = 1 - kr - kb
    from viewcomp.rt.media.frames import _chroma8

    cb = _chroma8(planes.u, h, w) / 8.0 - 128.0
    cr = _chroma8(planes.v, h, w) / 8.0 - 128.0
    y = planes.y.astype(np.float64)
    if color_range == "limited":
        y, cb, cr = (y - 16.0) * 255 / 219, cb * 255 / 224, cr * 255 / 224
    r = y + 2 * (1 - kr) * cr
    g = y - 2 * (1 - kb) * kb / kg * cb - 2 * (1 - kr) * kr / kg * cr
    b = y + 2 * (1 - kb) * cb
    ref = np.clip(np.rint(np.stack([r, g, b], -1)), 0, 255)
    assert np.abs(cpu - ref).max() <= 1


def test_render_to_host_framebuffer_flips(gl_ctx) -> None:
    model = synthetic_model("pixel", W, H)
    frame = smooth_frame(W, H, seed=4)
    rb = gl_ctx.renderbuffer((W + 10, H + 6), 4)
    fbo = gl_ctx.framebuffer(color_attachments=[rb])
    try:
        with Compensator(model, gl_ctx) as comp:
            comp.identity = True
            comp.upload(frame)
            fbo.clear()
            comp.render_to(fbo, origin=(4, 2), flip_y=True)
            raw = np.frombuffer(fbo.read(components=3, alignment=1), np.uint8)
            img = raw.reshape(H + 6, W + 10, 3)[2 : 2 + H, 4 : 4 + W]
            np.testing.assert_array_equal(img[::-1], frame)  # GL rows go bottom-up
            np.testing.assert_array_equal(comp.render(frame), frame)  # own FBO unaffected
    finally:
        fbo.release()
        rb.release()


def test_wrong_frame_size_is_a_clear_error(gl_ctx) -> None:
    with Compensator(synthetic_model("paper", W, H), gl_ctx) as comp:
        with pytest.raises(ValueError, match=r"frame must be uint8 \(96, 160, 3\)"):
            comp.render(np.zeros((10, 10, 3), np.uint8))


def test_release_frees_everything(gl_ctx) -> None:
    model = synthetic_model("pixel", 64, 48)
    frame = smooth_frame(64, 48)
    planes = rgb_to_yuv420p(frame)
    probe0 = live_gl_objects(gl_ctx)
    for _ in range(3):
        comp = Compensator(model, gl_ctx)
        comp.render(frame)
        comp.render_planes(planes)
        comp.identity = True
        comp.render(frame)
        assert comp.live_objects() > 10
        comp.release()
        assert comp.live_objects() == 0
        comp.release()  # idempotent
    assert live_gl_objects(gl_ctx) == probe0  # the driver agrees
    # context_gc queues every collected wrapper; none may still hold a live GL object.
    assert not [o for o in gl_ctx.objects if not isinstance(o, moderngl.InvalidObject)]


def _rss_kib() -> int:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGESIZE") // 1024


@pytest.mark.parametrize("method", ["pixel", "paper", "pixel-held"])
def test_soak_angle_changes_every_frame(gl_ctx, method) -> None:
    """2,000 frames, a new eye, tone (and paper model) each frame: no GL object/RSS growth.

    ``pixel-held``: the eye moves every 4th frame instead, so the view cache is rebuilt
    ~500 times (2 bands) and drawn from in between.
    """
    w, h = 128, 72
    planes = rgb_to_yuv420p(smooth_frame(w, h))
    out = np.empty((h, w, 3), np.uint8)
    held = method == "pixel-held"
    method = method.split("-")[0]
    model = synthetic_model(method, w, h)
    paths = set()
    with Compensator(model, gl_ctx, view_steps=2) as comp:
        for i in range(2000):
            if i == 200:
                objects0, rss0 = live_gl_objects(gl_ctx), _rss_kib()
            comp.set_angle(45 + ((i // 4 if held else i) % 90), 0.5, 0.035)
            comp.set_tone(0.5 + 0.001 * (i % 50), 0.02)
            if method == "paper":
                k = np.float32(1 + 0.001 * (i % 37))
                comp.update_model(model.Wc_inv * k, model.inv_lut, model.inv_lo, model.inv_hi * k)
            comp.identity = i % 7 == 0
            if i % 3:
                comp.render_planes(planes, out=out)
            else:
                comp.render(out, out=out)
            paths.add(comp.last_path)
        assert ("cached" in paths) == held
        assert live_gl_objects(gl_ctx) == objects0
        assert _rss_kib() <= rss0 * 1.05


def test_view_cache_policy_and_bands(gl_ctx) -> None:
    """Held eye: solve while the cache is built band by band, then cached; a move solves."""
    model = synthetic_model("pixel", 48, 20, seed=4)
    frame = smooth_frame(48, 20, seed=1)
    eye = eye_from_angle(70, 0.5, 0.035)
    ref = compensate(model, frame, eye, ALPHA, BETA)
    with Compensator(model, gl_ctx, view_hold=1, view_steps=3) as comp:
        comp.set_tone(ALPHA, BETA)
        paths = []
        for i in range(7):
            comp.set_eye(*(eye if i != 5 else eye_from_angle(71, 0.5, 0.035)))
            out = comp.render(frame)
            paths.append(comp.last_path)
            if i != 5:
                assert_close(out, ref)
        # 0: new eye; 1-3: bands 1..3 (the third completes it); 5: moved for one draw (no
        # rebuild begun); 6: back at the eye the cache still holds.
        assert paths == ["solve", "solve", "solve", "cached", "cached", "solve", "cached"]
        banded = comp._view[0].buffer.read()
    with Compensator(model, gl_ctx, view_hold=0, view_steps=1) as one:
        one.set_eye(*eye)
        one.set_tone(ALPHA, BETA)
        one.render(frame)
        assert one.last_path == "cached"
        # The bands add up to the one-pass cache, bit for bit.
        assert banded == one._view[0].buffer.read()


@pytest.mark.parametrize("cached", [False, True], ids=["solve", "cached"])
def test_wide_grid(gl_ctx, cached: bool) -> None:
    """3840 wide: the view cache's 5 texels per pixel do not fit one row of
    GL_MAX_TEXTURE_SIZE in the render target, which then holds 3 x 2 blocks."""
    w, h = 3840, 6
    if 5 * w <= int(gl_ctx.info["GL_MAX_TEXTURE_SIZE"]):
        pytest.skip("this driver fits 5 x 3840 texels in a row")  # llvmpipe: 16384, it does not
    model = synthetic_model("pixel", w, h, seed=8)
    frame = smooth_frame(w, h, seed=2)
    eye = eye_from_angle(60, 0.5, 0.035)
    with Compensator(model, gl_ctx, view_cache=cached, view_hold=0, view_steps=2) as comp:
        comp.set_eye(*eye)
        comp.set_tone(ALPHA, BETA)
        ref = compensate(model, frame, eye, ALPHA, BETA)
        for _ in range(2):  # the cache takes two draws (bands); the second draw uses it
            assert_close(comp.render(frame), ref)
        assert comp.last_path == ("cached" if cached else "solve")
        if cached:
            assert (comp._consts["VIEW_BX"], comp._consts["VIEW_BY"]) == (3, 2)
