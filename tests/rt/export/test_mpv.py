"""`viewcomp export-mpv`: the file's structure, its GLSL run through this project's GL
path against the numpy reference, and a real mpv under Xvfb.

The structure tests need nothing; the GLSL tests need OpenGL (marker ``gl``); the mpv tests
need Debian's mpv and Xvfb and skip without them (fail under VIEWCOMP_REQUIRE_GL=1).
"""

from __future__ import annotations

import json
import os
import shutil
import socket
import subprocess
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from tests.support.calibrations import small_calibration
from tests.support.mpv_hooks import run_hook, sections, textures
from tests.support.synthetic import smooth_frame
from viewcomp.calib.comp.compensation import Compensation, thumbnail
from viewcomp.calib.model.reference import compensate
from viewcomp.rt.export.mpv import (
    TONE_TABLE,
    TONE_TABLE_STEP,
    ExportError,
    export_mpv_shader,
    full_range_sample,
)
from viewcomp.rt.play.xvfb import Xvfb, xvfb_available

pytestmark = pytest.mark.usefixtures("session_gl_current")

W, H = 64, 32


@pytest.fixture(scope="module")
def cal() -> Any:
    return small_calibration(W, H, screen="magenta")


@pytest.fixture(scope="module")
def image() -> np.ndarray:
    return smooth_frame(W, H, seed=3)


def assert_like_the_shader(got: np.ndarray, want: np.ndarray, what: str) -> None:
    """The GL compensator's bound (tests/rt/gl/test_gl_compensate.py): <= 1 level in 99.9 % of
    pixel-channels and <= 3 anywhere."""
    d = np.abs(got.astype(np.int16) - want.astype(np.int16))
    print(f"{what}: max {d.max()} levels, {(d > 1).sum()} of {d.size} pixel-channels over 1")
    assert d.max() <= 3, f"{what}: max difference {d.max()} levels"
    assert np.mean(d > 1) <= 0.001, f"{what}: {np.mean(d > 1):.4%} of pixel-channels > 1"


def assert_levels_close(got: np.ndarray, want: np.ndarray, what: str) -> None:
    """At most 0.1 % of pixel-channels more than 1 level apart.

    A few can differ more: where the projector light y the formula solves for is within
    ~1e-7 of 0, float rounding decides between 0 and a tiny positive y, and the inverse
    response is steepest there (sqrt-sampled LUT, docs/RUNTIME.md): up to ~10 levels on
    that one pixel-channel. Both backends share this; it is not a bug of the export.
    """
    diff = np.abs(got.astype(int) - want.astype(int))
    print(f"{what}: max {diff.max()} levels, {(diff > 1).sum()} of {diff.size} "
          f"pixel-channels over 1")  # fmt: skip
    assert (diff > 1).sum() <= 0.001 * diff.size, what


# ----------------------------------------------------------------------- structure, math
def test_structure_of_a_fixed_angle_export(cal: Any, image: np.ndarray) -> None:
    text, info = export_mpv_shader(cal, angle=60.0, tone_sample=image, source="t.vcb")
    assert text.startswith("// viewcomp")
    blocks = sections(text)
    hook = blocks[0][0]
    assert hook["HOOK"] == ["OUTPUT"]
    assert hook["BIND"] == ["HOOKED", *(f"VC_ROW{k}" for k in range(3)), "VC_LUT"]
    assert "vec4 hook()" in blocks[0][1]
    names = [h["TEXTURE"][0] for h, _ in blocks[1:]]
    assert names == [*(f"VC_ROW{k}" for k in range(3)), "VC_LUT"]
    tex = textures(text)
    assert all(tex[f"VC_ROW{k}"].shape == (H, W, 4) for k in range(3))
    assert tex["VC_LUT"].shape == (3, 1024, 4)
    header = text[: text.index("//!")]
    assert "grid 64x32" in header and "angle 60" in header
    for _, body in blocks:  # nothing inside a body that mpv would take for a directive
        assert "//!" not in body
    assert (info.grid, info.param, info.precision) == ((W, H), False, 16)
    assert all(line.isascii() for line in text.split("\n"))


@pytest.mark.gl
@pytest.mark.parametrize("precision", [16, 32])
@pytest.mark.parametrize(("method", "angle"), [("pixel", 60.0), ("pixel", 120.0), ("paper", 45.0)])
def test_exported_glsl_matches_the_reference(
    gl_ctx: Any, cal: Any, image: np.ndarray, method: str, angle: float, precision: int
) -> None:
    text, info = export_mpv_shader(cal, method=method, angle=angle, tone_sample=image,
                                   precision=precision)  # fmt: skip
    eye = cal.eye(angle=angle)
    p = Compensation(cal, method)(thumbnail(image), eye)
    assert (info.alpha, info.beta) == (p.alpha, p.beta)  # what `viewcomp render` chooses
    ref = compensate(p.model, image, eye, p.alpha, p.beta)
    assert ref.std() > 0
    got = run_hook(gl_ctx, text, image)
    assert_levels_close(got, ref, f"exported GLSL ({method}, {precision} bits)")
    assert_like_the_shader(got, ref, f"exported GLSL ({method}, {precision} bits)")


@pytest.mark.gl
def test_exported_audience_matches_the_reference(gl_ctx: Any, cal: Any, image: np.ndarray) -> None:
    """An audience baked into the fixed-view rows: what `render --audience` computes, with
    the tone map Compensation chooses for the audience; one viewer is the eye's export."""
    from viewcomp.calib.world.audience import parse_audience

    v = cal.rig.viewer
    aud = parse_audience("60:120", v.distance, v.height or 0.0)
    text, info = export_mpv_shader(cal, audience=aud, tone_sample=image, precision=32)
    p = Compensation(cal, "pixel")(thumbnail(image), aud)
    assert (info.alpha, info.beta) == (p.alpha, p.beta)
    ref = compensate(p.model, image, aud, p.alpha, p.beta)
    got = run_hook(gl_ctx, text, image)
    assert_levels_close(got, ref, "exported GLSL (audience)")
    assert_like_the_shader(got, ref, "exported GLSL (audience)")
    assert "an audience of 7 viewers" in text[: text.index("//!")]
    one, _ = export_mpv_shader(cal, audience=parse_audience("75", v.distance, v.height or 0.0),
                               tone_sample=image)  # fmt: skip
    eye = cal.eye(angle=75.0)
    same, _ = export_mpv_shader(cal, eye=tuple(eye), tone_sample=image)
    assert one == same
    with pytest.raises(ExportError, match="pixel method"):
        export_mpv_shader(cal, audience=aud, method="paper")


@pytest.mark.gl
def test_precision_8_is_within_a_level_of_the_full_precision_export(
    gl_ctx: Any, cal: Any, image: np.ndarray
) -> None:
    """--precision 8 (a smooth base plus an 8-bit residual) against --precision 32 (exact
    float32 rows), both run through this project's GL path: <= 1 level in 99.9 % of
    pixel-channels, and a smaller file than 16 bits."""
    full, info32 = export_mpv_shader(cal, angle=60.0, tone_sample=image, precision=32)
    small, info8 = export_mpv_shader(cal, angle=60.0, tone_sample=image, precision=8)
    _, info16 = export_mpv_shader(cal, angle=60.0, tone_sample=image, precision=16)
    assert info8.bytes < info16.bytes < info32.bytes
    tex = textures(small)
    assert tex["VC_ROW0"].dtype == np.uint8 and tex["VC_BASE0"].shape == (H // 4, W // 4, 4)
    for frame in (
        image,
        np.kron(full_range_sample((H // 4, W // 4)), np.ones((4, 4, 1), np.uint8)),
    ):
        want = run_hook(gl_ctx, full, frame)
        assert_levels_close(run_hook(gl_ctx, small, frame), want, "precision 8 vs 32")
    with pytest.raises(ExportError, match="precision 8"):
        export_mpv_shader(cal, angle=60.0, param=True, precision=8)


@pytest.mark.gl
def test_param_export(gl_ctx: Any, cal: Any, image: np.ndarray) -> None:
    text, _ = export_mpv_shader(cal, angle=60.0, param=True, tone_sample=image)
    blocks = sections(text)
    par, value = blocks[0]
    assert par["PARAM"] == ["angle"] and par["TYPE"] == ["float"]
    assert par["MINIMUM"] == ["1.0"] and par["MAXIMUM"] == ["179.0"]
    assert value.strip() == "60.0"
    assert "HOOK" in blocks[1][0]
    comp = Compensation(cal, "pixel")
    sample = thumbnail(image)
    for angle in (60.0, 35.0):  # table points: the tone map baked for that angle
        eye = cal.eye(angle=angle)
        t = comp.tone_map(comp.base_model(), sample, eye)
        ref = compensate(comp.base_model(), image, eye, t.alpha, t.beta)
        got = run_hook(gl_ctx, text, image, angle)
        assert_levels_close(got, ref, f"PARAM at {angle:g} deg")
        assert_like_the_shader(got, ref, f"PARAM at {angle:g} deg")
    # Between table points the tone map is interpolated linearly (47.5: half way 45 .. 50).
    assert TONE_TABLE_STEP == 5.0 and 45.0 in TONE_TABLE
    t0, t1 = (comp.tone_map(comp.base_model(), sample, cal.eye(angle=a)) for a in (45.0, 50.0))
    eye = cal.eye(angle=47.5)
    alpha, beta = 0.5 * (t0.alpha + t1.alpha), 0.5 * (t0.beta + t1.beta)
    ref = compensate(comp.base_model(), image, eye, alpha, beta)
    assert_like_the_shader(run_hook(gl_ctx, text, image, 47.5), ref, "PARAM at 47.5 deg")


def test_export_errors_and_defaults(cal: Any) -> None:
    with pytest.raises(ExportError, match="paper"):
        export_mpv_shader(cal, method="paper", param=True)
    with pytest.raises(ExportError):
        export_mpv_shader(cal, angle=200.0)
    text, _ = export_mpv_shader(cal, method="paper", angle=45.0)
    assert "#define VC_A0 vec4(" in text and "VC_MAP0" not in text
    sample = full_range_sample()
    assert len(np.unique(sample.reshape(-1, 3), axis=0)) == 9
    _, conservative = export_mpv_shader(cal, angle=60.0)
    _, typical = export_mpv_shader(cal, angle=60.0, tone_sample=smooth_frame(W, H, seed=3))
    assert conservative.alpha <= typical.alpha


def test_cli_export(
    cal: Any, image: np.ndarray, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from viewcomp.cli import main

    bundle = tmp_path / "s.vcb"
    cal.save(bundle)
    png = tmp_path / "frame.png"
    cv2.imwrite(str(png), image[..., ::-1])
    out = tmp_path / "c.glsl"
    assert main(["export-mpv", str(bundle), "-o", str(out), "--angle", "60",
                 "--tone-from", str(png)]) == 0  # fmt: skip
    assert out.read_text().startswith("// viewcomp")
    assert not list(tmp_path.glob(".*partial*"))
    guard = tmp_path / "guard.lua"
    assert main(["export-mpv", str(bundle), "-o", str(out), "--angle", "60",
                 "--guard", str(guard)]) == 0  # fmt: skip
    from viewcomp.rt.export.mpv import guard_script

    assert guard.read_text() == guard_script()  # the guard itself, whole
    assert "stop(2," in guard.read_text() and "stop(3," in guard.read_text()
    assert f"--script={guard}" in capsys.readouterr().out
    with pytest.raises(SystemExit):  # never over the shader it writes
        main(["export-mpv", str(bundle), "-o", str(out), "--guard", str(out)])
    with pytest.raises(SystemExit):
        main(["export-mpv", str(bundle), "-o", str(out), "--alpha", "0.9"])


# ----------------------------------------------------------------------- a real mpv
def _need(what: str) -> None:
    if os.environ.get("VIEWCOMP_REQUIRE_GL") == "1":
        pytest.fail(f"{what} (VIEWCOMP_REQUIRE_GL=1)", pytrace=False)
    pytest.skip(what)


@pytest.fixture(scope="module")
def mpv_display() -> Any:
    if shutil.which("mpv") is None:
        _need("mpv is not installed (Debian package mpv)")
    if not xvfb_available():
        _need("Xvfb is not installed (Debian package xvfb)")
    with Xvfb((640, 480)) as x:
        yield x.display


def run_mpv(
    shader: Path, image: Path, vo: str, tmp: Path, *extra: str, size: tuple[int, int] | None = None
) -> tuple[np.ndarray | None, str]:
    """mpv shows ``image`` (or a video's first frame) through ``shader`` in a window of
    ``size`` (default: the image's size); returns the window's screenshot (None if mpv
    failed) and mpv's log."""
    sock = tmp / f"mpv-{vo}.sock"
    shot = tmp / f"shot-{vo}.png"
    for old in (sock, shot):  # from an earlier run in the same folder
        old.unlink(missing_ok=True)
    w, h = size or cv2.imread(str(image)).shape[1::-1]
    cmd = ["mpv", "--no-config", f"--vo={vo}", "--gpu-context=x11egl", "--gpu-sw",
           f"--glsl-shaders={shader}", "--dither-depth=no", f"--geometry={w}x{h}",
           "--border=no", "--pause", "--keep-open=always", "--osc=no", "--osd-level=0",
           "--audio=no", f"--input-ipc-server={sock}", "--screenshot-format=png",
           "--msg-level=all=warn", *extra, str(image)]  # fmt: skip
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        end = time.monotonic() + 60
        while not sock.exists() and time.monotonic() < end and p.poll() is None:
            time.sleep(0.05)
        if p.poll() is not None or not sock.exists():
            return None, p.communicate(timeout=10)[0]
        time.sleep(1.0)  # the first frame, shaders compiled
        c = socket.socket(socket.AF_UNIX)
        c.connect(str(sock))
        c.sendall(json.dumps({"command": ["screenshot-to-file", str(shot), "window"]}).encode()
                  + b"\n")  # fmt: skip
        while not shot.exists() and time.monotonic() < end:
            time.sleep(0.05)
        time.sleep(0.2)
        c.sendall(b'{"command": ["quit"]}\n')
        c.close()
        log = p.communicate(timeout=20)[0]
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
    if not shot.exists():
        return None, log
    return cv2.imread(str(shot))[..., ::-1].copy(), log


@pytest.mark.gl
@pytest.mark.parametrize(("vo", "precision"), [("gpu", "16"), ("gpu-next", "16"), ("gpu", "8")])
def test_real_mpv_matches_viewcomp_render(
    mpv_display: str, cal: Any, image: np.ndarray, tmp_path: Path, vo: str, precision: str
) -> None:
    from viewcomp.cli import main

    bundle = tmp_path / "s.vcb"
    cal.save(bundle)
    png = tmp_path / "frame.png"
    cv2.imwrite(str(png), image[..., ::-1])
    shader = tmp_path / "c.glsl"
    assert main(["export-mpv", str(bundle), "-o", str(shader), "--angle", "60",
                 "--tone-from", str(png), "--precision", precision]) == 0  # fmt: skip
    rendered = tmp_path / "render.png"
    assert main(["render", str(bundle), str(png), "-o", str(rendered), "--angle", "60",
                 "--quiet"]) == 0  # fmt: skip
    want = cv2.imread(str(rendered))[..., ::-1].astype(int)
    got, log = run_mpv(shader, png, vo, tmp_path)
    assert got is not None, log
    assert got.shape == want.shape
    assert_levels_close(got, want, f"\nmpv {vo} ({precision} bits) vs `viewcomp render`")


@pytest.mark.gl
def test_real_mpv_runs_the_param_code_path(
    gl_ctx: Any, mpv_display: str, cal: Any, image: np.ndarray, tmp_path: Path
) -> None:
    """Debian 12's mpv (libplacebo 4.208) rejects //!PARAM; with the parameter replaced by a
    constant, the same GLSL (eye from the angle, tone table) runs in mpv and gives what it
    gives in this project's GL path (test_param_export: that against the reference)."""
    text, _ = export_mpv_shader(cal, angle=60.0, param=True, tone_sample=image)
    start = text.index("//!PARAM")
    end = text.index("//!HOOK")
    concrete = text[:start] + text[end:]
    desc = concrete.index("\n", concrete.index("//!DESC")) + 1
    concrete = concrete[:desc] + "const float angle = 47.5;\n" + concrete[desc:]
    shader = tmp_path / "p.glsl"
    shader.write_text(concrete)
    png = tmp_path / "frame.png"
    cv2.imwrite(str(png), image[..., ::-1])
    got, log = run_mpv(shader, png, "gpu", tmp_path)
    assert got is not None, log
    want = run_hook(gl_ctx, text, image, 47.5)
    assert_levels_close(got, want, "\nPARAM code path, 47.5 deg, vo=gpu")


@pytest.mark.gl
@pytest.mark.slow
def test_real_mpv_registers_a_16_9_clip_like_render(
    mpv_display: str, cal: Any, tmp_path: Path
) -> None:
    """A 16:9 clip on the 2:1 grid (pillarboxed): mpv with the documented command line
    (mpv_args: the shader and the fit filter) shows what `viewcomp render` writes, bars
    included. Both are compared in render's output format (mpv's window encoded by the same
    writer, losslessly, and decoded by the same reader), so only the compensation differs."""
    from fractions import Fraction

    from tests.support.synthetic import write_clip
    from viewcomp.cli import main
    from viewcomp.rt.export.mpv import mpv_args
    from viewcomp.rt.media.frames import Planes, fit_rect, yuv420p_to_rgb
    from viewcomp.rt.media.video import VideoReader, VideoWriter

    def first_frame(path: Path, fit: tuple[int, int] | None = None) -> Planes:
        with VideoReader(path, fit=fit, audio="none") as reader:
            return next(p for p in reader if isinstance(p, Planes))

    bundle = tmp_path / "s.vcb"
    cal.save(bundle)
    clip = tmp_path / "clip.mp4"
    write_clip(str(clip), [smooth_frame(256, 144, seed=3)] * 3, 25, tone=False,
               options={"crf": "0", "preset": "ultrafast"})  # fmt: skip
    x0, _, fw, _ = fit_rect(256, 144, W, H, even=True)
    assert (x0, fw) == (4, 56)  # pillarboxed: 4 black columns each side
    fitted = tmp_path / "fitted.png"  # the frame as render fits it: its tone map
    cv2.imwrite(str(fitted), yuv420p_to_rgb(first_frame(clip, (W, H)))[..., ::-1])
    shader = tmp_path / "c.glsl"
    assert main(["export-mpv", str(bundle), "-o", str(shader), "--angle", "60",
                 "--tone-from", str(fitted)]) == 0  # fmt: skip
    rendered = tmp_path / "render.mp4"
    assert main(["render", str(bundle), str(clip), "-o", str(rendered), "--angle", "60",
                 "--quiet", "--crf", "0", "--smooth", "0"]) == 0  # fmt: skip
    out = first_frame(rendered)
    want = yuv420p_to_rgb(out).astype(int)
    args = [a for a in mpv_args(str(shader), (W, H)) if not a.startswith("--glsl-shaders=")]
    results = {}
    for name, extra in (("documented", args), ("without the filter", ["--dither-depth=no"])):
        got, log = run_mpv(shader, clip, "gpu", tmp_path, *extra, size=(W, H))
        assert got is not None, log
        again = tmp_path / f"mpv-{len(results)}.mp4"
        with VideoWriter(again, W, H, Fraction(25), crf=0, colorspace=out.colorspace) as wr:
            wr.write(np.ascontiguousarray(got))
        diff = np.abs(yuv420p_to_rgb(first_frame(again)).astype(int) - want)
        results[name] = diff
        print(
            f"\nmpv ({name}) vs render, 16:9 on 2:1: mean {diff.mean():.2f} levels, "
            f"bars {diff[:, :x0].mean():.2f}, picture {diff[:, x0 + 1 : x0 + fw - 1].mean():.2f}"
        )
    assert results["documented"].mean() < 1.5
    # Without the filter the maps are still read where the picture lies (the bars, outside
    # mpv's video rectangle, are not compensated; one column either side may be rounded).
    assert results["without the filter"][:, x0 + 1 : x0 + fw - 1].mean() < 1.5


@pytest.mark.gl
@pytest.mark.slow
def test_a_rejected_shader_fails_loudly(
    mpv_display: str, cal: Any, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Debian 12's mpv rejects the //!PARAM export and a shader that does not compile, and
    then plays uncompensated with exit status 0. With the documented command line (the
    guard script) it exits 2 instead, and `viewcomp check-mpv` exits 2 naming mpv's error;
    a good export plays (0) and passes the check (0)."""
    from tests.support.synthetic import write_clip
    from viewcomp.cli import main
    from viewcomp.rt.export.mpv import guard_script, mpv_args

    good, _ = export_mpv_shader(cal, angle=60.0)
    param, _ = export_mpv_shader(cal, angle=60.0, param=True)
    broken = good.replace("vec4 hook() {", "vec4 hook() { not glsl;")
    guard = tmp_path / "guard.lua"
    guard.write_text(guard_script())
    clip = tmp_path / "clip.mp4"
    write_clip(str(clip), [smooth_frame(W, H, seed=1)] * 50, 25, tone=False)
    for name, text, status, said in (("good", good, 0, ""), ("param", param, 2, "PARAM"),
                                     ("broken", broken, 2, "syntax error")):  # fmt: skip
        shader = tmp_path / f"{name}.glsl"
        shader.write_text(text)
        cmd = ["mpv", "--no-config", "--vo=gpu", "--gpu-context=x11egl", "--gpu-sw",
               *mpv_args(str(shader), (W, H), str(guard)), "--audio=no", "--osc=no",
               f"--geometry={W}x{H}", "--length=1", str(clip)]  # fmt: skip
        played = subprocess.run(cmd, capture_output=True, text=True, timeout=60)
        print(f"\n{name}: mpv exit status {played.returncode}")
        assert played.returncode == status, played.stdout + played.stderr
        assert main(["check-mpv", str(shader), "--headless"]) == status
        err = capsys.readouterr().err
        assert said in err and ("rejects" in err) == (status == 2), err
    # without the guard mpv plays the rejected shader uncompensated and says it succeeded
    plain = subprocess.run(["mpv", "--no-config", "--vo=gpu", "--gpu-context=x11egl",
                            "--gpu-sw", f"--glsl-shaders={tmp_path / 'param.glsl'}",
                            "--audio=no", "--length=1", str(clip)],
                           capture_output=True, text=True, timeout=60)  # fmt: skip
    assert plain.returncode == 0 and "PARAM" in plain.stdout + plain.stderr


@pytest.mark.gl
@pytest.mark.slow
def test_the_guard_tells_no_video_output_from_a_rejected_shader(
    mpv_display: str, cal: Any, tmp_path: Path
) -> None:
    """Under Xvfb without --gpu-sw mpv opens no video output (it refuses the software
    renderer): the guard exits 3 saying so and that the shader was not tried; a rejected
    shader exits 2 saying it was rejected. The two read differently."""
    from viewcomp.rt.export.mpv import guard_script

    good, _ = export_mpv_shader(cal, angle=60.0)
    shader = tmp_path / "good.glsl"
    shader.write_text(good)
    broken = tmp_path / "broken.glsl"
    broken.write_text(good.replace("vec4 hook() {", "vec4 hook() { not glsl;"))
    guard = tmp_path / "guard.lua"
    guard.write_text(guard_script())
    still = tmp_path / "still.png"
    cv2.imwrite(str(still), smooth_frame(W, H, seed=2)[..., ::-1])

    def play(path: Path, *context: str) -> subprocess.CompletedProcess[str]:
        cmd = ["mpv", "--no-config", "--vo=gpu", *context, f"--glsl-shaders={path}",
               f"--script={guard}", "--frames=1", "--audio=no", "--osc=no",
               f"--geometry={W}x{H}", str(still)]  # fmt: skip
        return subprocess.run(cmd, capture_output=True, text=True, timeout=60)

    no_output = play(shader)  # no --gpu-sw: mpv refuses llvmpipe, no context opens
    said = no_output.stdout + no_output.stderr
    assert no_output.returncode == 3, said
    assert "could not open a video output" in said and "not tried" in said
    assert "was rejected" not in said
    rejected = play(broken, "--gpu-context=x11egl", "--gpu-sw")
    said = rejected.stdout + rejected.stderr
    assert rejected.returncode == 2, said
    assert "compensation shader was rejected" in said and "video output (" not in said


def test_the_export_carries_its_check_value_and_texture_list(cal: Any) -> None:
    """The check value is the numpy reference's output for the check's still (block means),
    and the structure check finds a file cut before or inside its textures, or edited."""
    from viewcomp.rt.export.mpv_verify import (
        block_means,
        check_still,
        parse_check,
        structure_problems,
    )

    text, info = export_mpv_shader(cal, angle=60.0)
    grid, expected = parse_check(text) or ((0, 0), None)
    assert grid == (W, H) and expected is not None
    comp = Compensation(cal, "pixel")
    p = comp(full_range_sample(), cal.eye(angle=60.0))
    want = compensate(p.model, check_still((W, H)), cal.eye(angle=60.0), info.alpha, info.beta)
    assert np.abs(block_means(want) - expected).max() <= 0.01
    assert structure_problems(text) == []
    cut = text[: text.index("//!TEXTURE")]
    assert "no //!TEXTURE VC_ROW0" in structure_problems(cut)
    inside = text[: text.index("//!TEXTURE VC_ROW1") + 200]
    assert any("VC_ROW1 holds" in p for p in structure_problems(inside))
    last = text.rstrip("\n")
    assert any("VC_LUT holds" in p for p in structure_problems(last[:-8]))
    bare = "\n".join(ln for ln in text.split("\n") if not ln.startswith("// viewcomp t"))
    assert structure_problems(bare) != []  # a check line without the texture list: edited


@pytest.mark.gl
@pytest.mark.slow
def test_check_mpv_proves_the_hook_ran(
    mpv_display: str, cal: Any, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`viewcomp check-mpv` passes a good export (16 and 8 bits) only after comparing mpv's
    window with the file's check value; it fails (2) on a file cut before its textures (mpv
    would skip the hook silently), on an altered check value and on a hook that does
    nothing; a file without a check value (exported before) passes with a note."""
    from viewcomp.cli import main

    bundle = tmp_path / "s.vcb"
    cal.save(bundle)
    for precision in ("16", "8"):
        shader = tmp_path / f"c{precision}.glsl"
        assert main(["export-mpv", str(bundle), "-o", str(shader), "--angle", "60",
                     "--precision", precision]) == 0  # fmt: skip
        capsys.readouterr()
        for vo in ("gpu", "gpu-next") if precision == "16" else ("gpu",):
            assert main(["check-mpv", str(shader), "--headless", "--vo", vo]) == 0
            out = capsys.readouterr().out
            print(out)
            assert "as exported" in out, out
    good = (tmp_path / "c16.glsl").read_text()
    start = good.index("mean levels ") + len("mean levels ")
    value = good[start : good.index(" ", start)]
    edits = {
        "cut": (good[: good.index("//!TEXTURE")], 2, "no //!TEXTURE VC_ROW0"),
        "altered": (
            good[:start] + f"{float(value) + 50:.2f}" + good[start + len(value) :],
            2,
            "did not run as exported",
        ),
        "noop": (
            good.replace("vec4 hook() {", "vec4 hook() { return HOOKED_texOff(0);"),
            2,
            "did not run as exported",
        ),
        "old": (
            "\n".join(ln for ln in good.split("\n") if not ln.startswith("// viewcomp ")),
            0,
            "could not be verified",
        ),
    }
    for name, (text, status, said) in edits.items():
        shader = tmp_path / f"{name}.glsl"
        shader.write_text(text)
        assert main(["check-mpv", str(shader), "--headless"]) == status, name
        got = capsys.readouterr()
        print(f"\n{name}: {got.out}{got.err}")
        assert said in got.out + got.err, name


@pytest.mark.gl
@pytest.mark.parametrize("angle", [60.0, 62.5])
def test_param_check_value_is_what_the_hook_outputs(gl_ctx: Any, cal: Any, angle: float) -> None:
    """The //!PARAM export's check value (the default angle, the tone table interpolated as
    the hook does) is what its GLSL outputs for the check's still (Debian's mpv cannot run
    it: this project's GL path instead)."""
    from viewcomp.rt.export.mpv_verify import block_means, check_still, parse_check

    text, _ = export_mpv_shader(cal, angle=angle, param=True)
    grid, expected = parse_check(text) or ((0, 0), np.zeros(1))
    got = block_means(run_hook(gl_ctx, text, check_still(grid), angle))
    print(f"\nPARAM at {angle} deg: max {np.abs(got - expected).max():.2f} levels")
    assert np.abs(got - expected).max() <= 3.0
