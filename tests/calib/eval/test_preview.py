"""`viewcomp preview`: the forward prediction, its agreement with `evaluate`, the picture."""

from __future__ import annotations

import re
import subprocess
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.support.calibrations import small_calibration
from viewcomp.calib.comp.compensation import Compensation, thumbnail
from viewcomp.calib.eval.evaluate import World, sweep
from viewcomp.calib.eval.preview import BAND, encode8, predict
from viewcomp.calib.eval.testimages import natural_images
from viewcomp.calib.io.imageio import read_rgb8, write_png
from viewcomp.calib.model.reference import (
    compensate,
    lut_inverse,
    predict_view,
    target_to_projector,
    white_response,
)


@pytest.fixture(scope="module")
def world() -> World:
    return World.make(seed=0, size=(160, 80))


@pytest.mark.parametrize("method", ["pixel", "paper"])
def test_predict_view_inverts_the_compensation(method: str) -> None:
    """Where nothing clips, the predicted view of the compensated frame is the target
    alpha C_w + beta that the compensation solved for (a fixed, dimming tone map, so that most
    pixels are inside the screen's range whatever the tone map would choose)."""
    cal = small_calibration(64, 32, screen="magenta")
    comp = Compensation(cal, method)
    eye = cal.eye(60.0)
    rng = np.random.default_rng(1)
    image = rng.integers(60, 160, (32, 64, 3), dtype=np.uint8)
    p = comp(thumbnail(image), eye)
    p = replace(p, alpha=0.6, beta=0.0)
    out = compensate(p.model, image, eye, p.alpha, p.beta)
    target = p.alpha * white_response(p.model, image) + p.beta
    seen = predict_view(p.model, out, eye)
    inside = np.all((out > 2) & (out < 253), axis=-1)
    assert inside.mean() > 0.5
    err = np.abs(seen - target)[inside] / np.maximum(target[inside], 1e-3)
    # back through the compensation's own inverse: the projector levels it came from
    y = target_to_projector(p.model, seen, eye)
    if method == "pixel":
        y = np.clip(y, 0.0, 1.0)
    back = 255.0 * lut_inverse(p.model.inv_lut, p.model.inv_lo, p.model.inv_hi, y)
    levels = np.abs(back - out)[inside]
    print(f"\n{method}: prediction vs target, relative error median {np.median(err):.4f}; "
          f"levels p99 {np.percentile(levels, 99):.3f} max {levels.max():.3f}")  # fmt: skip
    assert np.median(err) < 0.01
    assert np.percentile(levels, 99) < 0.5 and levels.max() < 3.0
    # the same frame through compensate() again gives the same levels
    again = compensate(p.model, image, eye, p.alpha, p.beta)
    assert np.array_equal(again, out)


def test_preview_of_magenta_glossy_matches_evaluate(world: World) -> None:
    """The compensated column's predicted dE is below the uncompensated one's and within 5 %
    of what `evaluate` computes for the same case (screen, image, angle) from the
    simulator's truth: evaluate's views are the simulated eye's, the preview's the fitted
    model's, so they agree only as far as the model fits the screen."""
    h, w = world.shape
    name, image = next(iter(natural_images(w, h).items()))
    rows = sweep(world, screens=["magenta"], angles=[60], images={name: image})
    de_eval = rows[0]["de"]
    case = world.case("magenta")
    p = predict(case.pixel, image, world.eye(60))
    print(f"\nmagenta glossy, {name} at 60 degrees: predicted dE uncompensated "
          f"{p.de_uncompensated:.2f} (evaluate {de_eval['original']:.2f}), compensated "
          f"{p.de_compensated:.2f} (evaluate {de_eval['pixel_theta']:.2f})")  # fmt: skip
    assert p.de_compensated < p.de_uncompensated
    assert p.de_compensated == pytest.approx(de_eval["pixel_theta"], rel=0.05)
    assert p.de_uncompensated == pytest.approx(de_eval["original"], rel=0.05)
    assert p.de_compensated != pytest.approx(de_eval["original"], rel=0.05)  # tells them apart


def test_encode8_is_the_camera_response(world: World) -> None:
    cal = world.case("red").cal
    lin = np.linspace(0, 1, 256, dtype=np.float32)[None, :, None].repeat(3, axis=2)
    enc = encode8(cal, lin)
    assert enc[0, 0, 0] == 0 and enc[0, -1, 0] == 255
    assert enc[0, 128, 0] > 128  # sRGB lifts the mid-tones


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "viewcomp", *args], capture_output=True,
                          text=True, timeout=300)  # fmt: skip


@pytest.fixture(scope="module")
def magenta(tmp_path_factory: pytest.TempPathFactory) -> tuple[Any, Path]:
    """A simulated glossy magenta screen's calibration at 64x32 and its saved bundle."""
    cal = small_calibration(64, 32, screen="magenta")
    bundle = tmp_path_factory.mktemp("preview") / "screen.vcb"
    cal.save(bundle)
    return cal, bundle


def test_cli_preview_image_and_video(tmp_path: Path, magenta: tuple[Any, Path]) -> None:
    from tests.support.synthetic import make_test_video

    _, bundle = magenta
    photo = tmp_path / "photo.png"
    write_png(photo, natural_images(128, 64)["astronaut"])
    out = tmp_path / "seen.png"
    r = _cli("preview", str(bundle), str(photo), "-o", str(out), "--angle", "60")
    assert r.returncode == 0, r.stderr
    assert "uncompensated dE" in r.stdout and "compensated (per-pixel method) dE" in r.stdout
    assert r.stderr == ""
    pic = read_rgb8(out)
    assert pic.shape[1] == 4 * 64 + 3 * 4  # four columns and three gaps
    assert np.all(pic[:3] == BAND)  # the title band is dark: labels read on any picture
    clip = tmp_path / "clip.mp4"
    make_test_video(str(clip), 128, 64, seconds=1.0, rate=10, audio=False)
    sheet = tmp_path / "sheet.png"
    r = _cli("preview", str(bundle), str(clip), "-o", str(sheet), "--eye", "0.1,0.0,0.5",
             "--frames", "3")  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert "3 frames (mean)" in r.stdout
    assert read_rgb8(sheet).shape[0] > 3 * 32
    for bad in (["-o", str(tmp_path / "x.jpg")], ["-o", str(photo)]):
        r = _cli("preview", str(bundle), str(photo), "--angle", "60", *bad)
        assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr


def test_audience_preview_one_row_per_viewer(tmp_path: Path, magenta: tuple[Any, Path]) -> None:
    """--audience: one row per viewer, each what that viewer sees of the audience's
    compensation, and the printed error is their mean. (Whether the audience's image beats
    another is a property of the scene: `evaluate --protocol audience` measures it.)"""
    from viewcomp.calib.comp.compensation import Compensation
    from viewcomp.calib.world.audience import zone

    cal, bundle = magenta
    photo = tmp_path / "photo.png"
    write_png(photo, natural_images(64, 32)["coffee"])
    out = tmp_path / "seen.png"
    r = _cli("preview", str(bundle), str(photo), "-o", str(out), "--audience", "60:120:3")
    assert r.returncode == 0, r.stderr
    assert "over the 3 viewers" in r.stdout
    one = tmp_path / "one.png"
    assert _cli("preview", str(bundle), str(photo), "-o", str(one), "--angle", "60").returncode == 0
    assert read_rgb8(out).shape[0] > 2.5 * (read_rgb8(one).shape[0] - 30)
    v = cal.rig.viewer
    aud = zone(60, 120, 3, v.distance, v.height)
    comp = Compensation(cal, "pixel")
    image = natural_images(64, 32)["coffee"]
    seen = [predict(comp, image, e, aud) for e in aud.eyes]
    assert (
        f"compensated (per-pixel method) dE {np.mean([p.de_compensated for p in seen]):.1f}"
        in r.stdout
    )
    assert not np.array_equal(seen[0].compensated, seen[2].compensated)  # seats differ
    assert all(np.array_equal(p.projected, seen[0].projected) for p in seen)  # one image


def test_an_underexposed_calibration_never_previews_better(tmp_path: Path) -> None:
    """The same screen calibrated from captures at 0.15 of the default exposure: the preview,
    on the absolute scale (the white screen at full output at REFERENCE_WHITE), reports a
    larger error than the well-exposed calibration's, not a smaller one (in the camera's own
    units it reported 8.5 against 14.7)."""
    errors = {}
    for name, extra in (("dim", ["--exposure", "0.15"]), ("good", [])):
        caps, bundle, pic = tmp_path / name, tmp_path / f"{name}.vcb", tmp_path / f"{name}.png"
        for args in (
            ["simulate", str(caps), "--screen", "magenta", "--gloss", "glossy",
             "--size", "160x80", *extra],
            ["calibrate", str(caps), "-o", str(bundle)],
        ):  # fmt: skip
            done = _cli(*args)
            assert done.returncode == 0, done.stderr
        image = natural_images(160, 80)["astronaut"]
        src = tmp_path / "astronaut.png"
        write_png(src, image)
        done = _cli("preview", str(bundle), str(src), "-o", str(pic), "--angle", "60")
        assert done.returncode == 0, done.stderr
        errors[name] = float(re.search(r"compensated \(per-pixel method\) dE ([0-9.]+)",
                                       done.stdout).group(1))  # fmt: skip
    print(f"\npredicted dE at 60 degrees: under-exposed {errors['dim']}, well {errors['good']}")
    assert errors["dim"] > errors["good"]
