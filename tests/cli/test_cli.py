"""The commands end to end on small sizes, and their error messages."""

import json
from pathlib import Path

import numpy as np
import pytest

from viewcomp.calib.io.imageio import read_image, write_png
from viewcomp.cli import COMMANDS, main

SIZE = "96x48"


@pytest.fixture(scope="module")
def calib(tmp_path_factory):
    d = tmp_path_factory.mktemp("cli")
    assert main(["simulate", str(d / "caps"), "--size", SIZE, "--screen", "red"]) == 0
    assert main(["calibrate", str(d / "caps"), "-o", str(d / "red.vcb")]) == 0
    return d


def test_help_of_every_command(capsys):
    for name in COMMANDS:
        with pytest.raises(SystemExit) as e:
            main([name, "--help"])
        assert e.value.code == 0
        assert "usage: viewcomp" in capsys.readouterr().out


def test_shared_options_mean_the_same_everywhere(capsys):
    """--angle/--eye, the tone map and the simulator's options are declared once: the same
    type, default and help in every command that takes them (the angle's default and note
    aside); calibrate's blur is --mixing-blur-px."""
    import argparse

    from viewcomp.cli import build_parser

    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    options = {
        name: {o: act for act in cmd._actions for o in act.option_strings}
        for name, cmd in sub.choices.items()
    }
    takes = {
        "--eye": ("render", "play", "export-mpv"),
        "--angle": ("render", "play", "export-mpv"),
        "--method": ("render", "play", "export-mpv"),
        "--lambda": ("render", "play", "export-mpv"),
        "--smooth": ("render", "play"),
        "--screen": ("simulate", "capture", "demo"),
        "--gloss": ("simulate", "capture"),
        "--seed": ("simulate", "capture", "demo", "evaluate"),
        "--space": ("simulate", "evaluate"),
    }
    for flag, names in takes.items():
        seen = set()
        for name in names:
            act = options[name][flag]
            text = act.help.split(";")[0].rstrip(")") if flag == "--angle" else act.help
            default = None if flag == "--angle" else act.default
            seen.add((act.type, default, act.metavar, act.dest, text, tuple(act.choices or ())))
        assert len(seen) == 1, (flag, seen)
    assert options["simulate"]["--size"].help == options["capture"]["--sim-size"].help
    helps = {}
    for name in ("calibrate",):
        with pytest.raises(SystemExit):
            main([name, "--help"])
        helps[name] = capsys.readouterr().out
    assert "--mixing-blur-px PX" in helps["calibrate"] and "--smooth" not in helps["calibrate"]
    with pytest.raises(SystemExit) as e:
        main(["calibrate", "caps", "-o", "x.vcb", "--smooth", "3"])
    assert e.value.code == 2
    for bad in ("nan", "-1"):
        with pytest.raises(SystemExit) as e:
            main(["calibrate", "caps", "-o", "x.vcb", "--mixing-blur-px", bad])
        assert e.value.code == 2
    assert "finite number >= 0" in capsys.readouterr().err


def test_patterns_writes_table1(tmp_path):
    assert main(["patterns", str(tmp_path), "--size", "64x32"]) == 0
    ramp = read_image(tmp_path / "ramp.png")
    assert ramp.shape == (32, 64, 3) and ramp[0, 0, 0] == 0 and ramp[0, -1, 0] == 255
    np.testing.assert_array_equal(read_image(tmp_path / "red.png")[0, 0], [130, 110, 110])


def test_calibrate_prints_fit_quality(calib, tmp_path, capsys):
    assert main(["calibrate", str(calib / "caps"), "-o", str(tmp_path / "b.vcb")]) == 0
    out = capsys.readouterr().out
    assert "per-pixel" in out and "rms" in out and "R^2" in out


def test_render_cpu_image_and_identity(calib, tmp_path):
    src = tmp_path / "in.png"
    rng = np.random.default_rng(0)
    img = rng.integers(0, 256, (48, 96, 3), dtype=np.uint8)
    write_png(src, img)
    bundle = str(calib / "red.vcb")
    out = tmp_path / "out.png"
    assert main(["render", bundle, str(src), "-o", str(out), "--angle", "60", "--backend",
                 "cpu", "--quiet"]) == 0  # fmt: skip
    comp = read_image(out)
    assert comp.shape == (48, 96, 3) and comp.dtype == np.uint8
    assert np.abs(comp.astype(int) - img).mean() > 5  # it did compensate
    ident = tmp_path / "ident.png"
    assert main(["render", bundle, str(src), "-o", str(ident), "--eye", "0.1,0.0,0.5",
                 "--backend", "cpu", "--identity", "--quiet"]) == 0  # fmt: skip
    np.testing.assert_array_equal(read_image(ident), img)


def test_render_letterboxes_another_size(calib, tmp_path):
    src = tmp_path / "square.png"
    write_png(src, np.full((60, 60, 3), 200, np.uint8))
    out = tmp_path / "out.png"
    assert main(["render", str(calib / "red.vcb"), str(src), "-o", str(out), "--angle", "90",
                 "--backend", "cpu", "--identity", "--quiet"]) == 0  # fmt: skip
    res = read_image(out)
    assert res.shape == (48, 96, 3)
    assert res[24, 48].tolist() == [200, 200, 200] and res[24, 2].tolist() == [0, 0, 0]


def test_errors_name_the_cause_without_traceback(calib, tmp_path, capsys):
    assert main(["calibrate", str(tmp_path / "nowhere"), "-o", str(tmp_path / "x.vcb")]) == 2
    err = capsys.readouterr().err
    assert "nowhere" in err and "Traceback" not in err
    bad = tmp_path / "bad.vcb"
    data = (calib / "red.vcb").read_bytes()
    bad.write_bytes(data[: len(data) // 3])
    src = tmp_path / "in.png"
    write_png(src, np.zeros((48, 96, 3), np.uint8))
    out = tmp_path / "out.png"
    assert main(["render", str(bad), str(src), "-o", str(out), "--angle", "60",
                 "--backend", "cpu", "--quiet"]) == 2  # fmt: skip
    err = capsys.readouterr().err
    assert "bad.vcb" in err and "viewcomp calibrate" in err and "Traceback" not in err
    assert not out.exists()
    with pytest.raises(SystemExit) as e:
        main(["render", str(calib / "red.vcb"), str(src), "-o", str(out), "--eye", "1,2"])
    assert e.value.code == 2
    assert "X,Y,Z" in capsys.readouterr().err


def test_evaluate_table2_report(tmp_path):
    assert main(["evaluate", "-o", str(tmp_path), "--protocol", "table2", "--size", "64x32",
                 "--quiet"]) == 0  # fmt: skip
    rep = json.loads((tmp_path / "report.json").read_text())
    rows = rep["table2"]
    assert len(rows) == 18
    keys = {"original", "paper_90", "paper_theta", "pixel_90", "pixel_theta", "oracle"}
    for r in rows:
        assert set(r) >= {"screen", "image", "seen_at", "sse"}
        assert keys <= set(r["sse"]) and r["screen"] in ("red", "green", "blue")
        assert r["seen_at"] in (60, 90) and len(r["image"]) == 3
        theta = f"paper_{r['seen_at']}"
        assert r["sse"]["paper_theta"] == r["sse"][theta]
    for f in ("report.md", "phong_fit.png", "tonemap_tradeoff.png"):
        assert (tmp_path / f).stat().st_size > 0


def test_sweep_rows_and_checks():
    from viewcomp.calib.eval.evaluate import World, check_sweep, sweep, sweep_means
    from viewcomp.calib.eval.testimages import natural_images

    world = World.make(size=(64, 32))
    imgs = dict(list(natural_images(64, 32).items())[:1])
    rows = sweep(world, screens=("red",), angles=(60, 90), images=imgs)
    assert len(rows) == 2 and all(set(r["de"]) >= {"oracle", "pixel_theta"} for r in rows)
    means = sweep_means(rows)
    checks = check_sweep(means)
    assert set(checks["off90_pixel_theta_le_both_90"]) == {"60"}


def test_values_that_begin_with_a_minus(calib, tmp_path, capsys):
    """A viewer left of the screen's centre has x < 0: `--eye -0.2,0,0.8` is a value, not an
    option (argparse said "expected one argument"); it renders as `--eye=-0.2,0,0.8` does.
    A negative size reaches the size's own check."""
    src = tmp_path / "in.png"
    write_png(src, np.random.default_rng(1).integers(0, 256, (48, 96, 3), dtype=np.uint8))
    bundle = str(calib / "red.vcb")
    a, b = tmp_path / "a.png", tmp_path / "b.png"
    assert main(["render", bundle, str(src), "-o", str(a), "--eye", "-0.2,0,0.8",
                 "--backend", "cpu", "--quiet"]) == 0  # fmt: skip
    assert main(["render", bundle, str(src), "-o", str(b), "--eye=-0.2,0,0.8",
                 "--backend", "cpu", "--quiet"]) == 0  # fmt: skip
    np.testing.assert_array_equal(read_image(a), read_image(b))
    with pytest.raises(SystemExit) as exc:
        main(["simulate", str(tmp_path / "s"), "--size", "-5x10"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "-5x10" in err and "expected one argument" not in err


def test_render_tone_choices(calib, tmp_path, capsys):
    src = tmp_path / "in.png"
    img = np.random.default_rng(1).integers(0, 256, (48, 96, 3), dtype=np.uint8)
    write_png(src, img)
    bundle = str(calib / "red.vcb")
    outs = {}
    for tone in ("paper", "global", "adaptive"):
        out = tmp_path / f"{tone}.png"
        assert main(["render", bundle, str(src), "-o", str(out), "--angle", "60", "--backend",
                     "cpu", "--tone", tone, "--quiet"]) == 0  # fmt: skip
        outs[tone] = read_image(out).astype(int)
    assert np.abs(outs["adaptive"] - outs["global"]).mean() > 1  # a different tone map
    assert np.abs(outs["paper"] - outs["global"]).mean() > 0
    bad = tmp_path / "bad.png"
    with pytest.raises(SystemExit) as exc:  # a usage error exits as argparse does
        main(["render", bundle, str(src), "-o", str(bad), "--angle", "60", "--tone", "adaptive",
              "--method", "paper", "--quiet"])  # fmt: skip
    assert exc.value.code == 2
    assert "--method pixel" in capsys.readouterr().err and not bad.exists()


@pytest.mark.gl
def test_render_adaptive_on_the_gl_backend(calib, tmp_path):
    """The GL backend draws the same adaptive map as the numpy reference (the field chosen on
    the CPU, the shader's soft clip): within a level or two."""
    src = tmp_path / "in.png"
    write_png(src, np.random.default_rng(2).integers(0, 256, (48, 96, 3), dtype=np.uint8))
    outs = {}
    for backend in ("cpu", "gl"):
        out = tmp_path / f"{backend}.png"
        assert main(["render", str(calib / "red.vcb"), str(src), "-o", str(out), "--angle", "60",
                     "--tone", "adaptive", "--backend", backend, "--quiet"]) == 0  # fmt: skip
        outs[backend] = read_image(out).astype(int)
    d = np.abs(outs["gl"] - outs["cpu"])
    assert d.max() <= 3 and np.mean(d > 1) <= 0.001
    assert outs["gl"].std() > 5


def test_the_hardware_estimate_counts_the_materials(tmp_path: Path) -> None:
    """`evaluate --protocol hardware --materials DIR` runs 6 rows per screen (glossy magenta
    and each material): the time it announces grows with the folder (it said the one-screen
    figure whatever the folder held)."""
    import argparse

    from viewcomp.commands.evaluate import _estimate

    def said(materials: Path | None) -> float:
        ns = argparse.Namespace(protocol="hardware", materials=materials, space="projector")
        text = _estimate(ns, (320, 160))
        value = float(text.split()[1])
        return value * 60 if text.split()[2] == "minutes" else value

    for name in ("a", "b", "c"):
        (tmp_path / f"{name}.npz").write_bytes(b"")
    assert said(tmp_path) == pytest.approx(4 * said(None))
