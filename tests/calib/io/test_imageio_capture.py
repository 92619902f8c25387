"""Image files, atomic writes and the capture-set folder."""

from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest

from viewcomp.calib.io.atomic import atomic_open
from viewcomp.calib.io.captureset import (
    REQUIRED,
    find_capture,
    read_capture_set,
    write_capture_set,
)
from viewcomp.calib.io.imageio import (
    CaptureError,
    read_image,
    read_rgb8,
    to_linear,
    write_npy,
    write_png,
)
from viewcomp.calib.world.response import parse_response
from viewcomp.calib.world.rig import CaptureSpec, Rig, RigError, default_rig

W, H = 32, 16


def _rig(space: str = "projector") -> Rig:
    rig = default_rig()
    return replace(
        rig,
        projector=replace(rig.projector, resolution=(W, H)),
        camera=replace(rig.camera, resolution=(2 * W, 2 * H)),
        capture=CaptureSpec(space=space),  # type: ignore[arg-type]
    )


def _images(seed: int, dtype: type = np.uint8, names: tuple[str, ...] = REQUIRED) -> dict:
    rng = np.random.default_rng(seed)
    top = np.iinfo(dtype).max
    return {n: rng.integers(0, top, (H, W, 3), endpoint=True).astype(dtype) for n in names}


def _no_temp_files(folder: Path) -> bool:
    return not [p for p in folder.rglob("*") if p.name.startswith(".")]


# --- imageio --------------------------------------------------------------------------------


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
def test_png_round_trip_keeps_rgb_order(tmp_path: Path, dtype: type) -> None:
    img = np.zeros((H, W, 3), dtype)
    img[..., 0] = np.iinfo(dtype).max  # pure red
    img[0, 0] = (1, 2, 3)
    write_png(tmp_path / "a.png", img)
    back = read_image(tmp_path / "a.png")
    assert back.dtype == dtype and back.shape == (H, W, 3)
    assert np.array_equal(back, img)
    assert _no_temp_files(tmp_path)


def test_gray_and_alpha_are_promoted_and_dropped(tmp_path: Path) -> None:
    gray = np.arange(W * H, dtype=np.uint8).reshape(H, W)
    write_png(tmp_path / "g.png", gray)
    g = read_image(tmp_path / "g.png")
    assert g.shape == (H, W, 3) and np.array_equal(g[..., 2], gray)
    bgra = np.zeros((H, W, 4), np.uint8)
    bgra[..., 0] = 200  # blue in OpenCV order
    bgra[..., 3] = 7
    cv2.imwrite(str(tmp_path / "a.png"), bgra)
    rgb = read_image(tmp_path / "a.png")
    assert rgb.shape == (H, W, 3) and np.array_equal(rgb[0, 0], [0, 0, 200])


def test_tiff_16bit_and_npy(tmp_path: Path) -> None:
    img = _images(1, np.uint16)["red"]
    cv2.imwrite(str(tmp_path / "t.tif"), img[..., ::-1])
    assert np.array_equal(read_image(tmp_path / "t.tif"), img)
    lin = np.linspace(0, 1, H * W * 3, dtype=np.float32).reshape(H, W, 3)
    write_npy(tmp_path / "x.npy", lin)
    back = read_image(tmp_path / "x.npy")
    assert back.dtype == np.float32 and np.array_equal(back, lin)
    assert np.array_equal(to_linear(back, "srgb"), lin)  # .npy is already linear


def test_to_linear_scales_then_decodes() -> None:
    srgb = parse_response("srgb")
    raw8 = np.full((2, 2, 3), 128, np.uint8)
    raw16 = np.full((2, 2, 3), 128 * 257, np.uint16)
    expect = srgb.decode(np.float32(128 / 255))
    for raw in (raw8, raw16):
        lin = to_linear(raw, srgb)
        assert lin.dtype == np.float32 and lin.shape == (2, 2, 3)
        assert lin == pytest.approx(np.full((2, 2, 3), expect), abs=1e-6)
    assert to_linear(np.full((1, 1, 3), 255, np.uint8), "linear") == pytest.approx(1.0)


def test_read_errors(tmp_path: Path) -> None:
    with pytest.raises(CaptureError, match="not found"):
        read_image(tmp_path / "missing.png")
    (tmp_path / "junk.png").write_bytes(b"this is not a png")
    with pytest.raises(CaptureError, match=r"cannot decode .*junk\.png"):
        read_image(tmp_path / "junk.png")
    (tmp_path / "empty.png").write_bytes(b"")
    with pytest.raises(CaptureError, match=r"empty\.png: is empty \(0 bytes\)"):
        read_image(tmp_path / "empty.png")
    with pytest.raises(CaptureError, match="is a folder, not a file"):
        read_image(tmp_path)
    (tmp_path / "loop.png").symlink_to(tmp_path / "loop.png")
    with pytest.raises(CaptureError, match="loop of symbolic links"):
        read_image(tmp_path / "loop.png")
    cv2.imwrite(str(tmp_path / "f.tif"), np.zeros((4, 4, 3), np.float32))
    with pytest.raises(CaptureError, match=r"8- or 16-bit.*\.npy"):
        read_image(tmp_path / "f.tif")
    np.save(tmp_path / "i.npy", np.zeros((4, 4, 3), np.uint8))
    with pytest.raises(CaptureError, match="float linear"):
        read_image(tmp_path / "i.npy")
    np.save(tmp_path / "o.npy", np.array([{"a": 1}], dtype=object), allow_pickle=True)
    with pytest.raises(CaptureError, match="cannot decode"):
        read_image(tmp_path / "o.npy")


def test_read_rgb8_reads_content_images_as_8_bit_rgb(tmp_path: Path) -> None:
    img = np.zeros((H, W, 3), np.uint8)
    img[..., 0] = 200  # red
    cv2.imwrite(str(tmp_path / "a.jpg"), img[..., ::-1])
    got = read_rgb8(tmp_path / "a.jpg")
    assert got.dtype == np.uint8 and got.shape == (H, W, 3)
    assert abs(int(got[..., 0].mean()) - 200) <= 2 and got[..., 2].max() <= 5
    cv2.imwrite(str(tmp_path / "b.png"), np.full((H, W), 40000, np.uint16))  # 16-bit gray
    got = read_rgb8(tmp_path / "b.png")
    assert got.dtype == np.uint8 and got.shape == (H, W, 3) and np.all(got == 40000 >> 8)
    (tmp_path / "empty.png").write_bytes(b"")
    (tmp_path / "folder.png").mkdir()
    for name, phrase in (("missing.png", "not found"), ("empty.png", "empty"),
                         ("folder.png", "not a file")):  # fmt: skip
        with pytest.raises(CaptureError, match=phrase):
            read_rgb8(tmp_path / name)
        with pytest.raises(CaptureError, match=phrase):
            read_image(tmp_path / name)


def test_to_linear_looks_up_exactly_what_decoding_computes() -> None:
    resp = parse_response("srgb")
    for dtype in (np.uint8, np.uint16):
        top = np.iinfo(dtype).max
        raw = np.random.default_rng(1).integers(0, top, (H, W, 3), endpoint=True).astype(dtype)
        direct = resp.decode(raw.astype(np.float32) / np.float32(top))
        assert np.array_equal(to_linear(raw, resp), direct)


def test_write_refusals(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="object"):
        write_npy(tmp_path / "o.npy", np.array([None], dtype=object))
    with pytest.raises(ValueError, match="uint8 or uint16"):
        write_png(tmp_path / "f.png", np.zeros((2, 2, 3), np.float32))
    with pytest.raises(ValueError, match=r"\.png"):
        write_png(tmp_path / "f.jpg", np.zeros((2, 2, 3), np.uint8))
    assert list(tmp_path.iterdir()) == []


def test_atomic_write_leaves_no_temp_file_on_error(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    target = tmp_path / "keep.png"
    old = np.full((H, W, 3), 9, np.uint8)
    write_png(target, old)
    with pytest.raises(RuntimeError, match="boom"), atomic_open(target) as f:
        f.write(b"half")
        raise RuntimeError("boom")
    assert np.array_equal(read_image(target), old)

    def failing_replace(src: str, dst: str) -> None:
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", failing_replace)
    with pytest.raises(OSError, match="disk full"):
        write_png(target, np.zeros((H, W, 3), np.uint8))
    with pytest.raises(OSError, match="disk full"):
        write_npy(tmp_path / "new.npy", np.zeros(3))
    monkeypatch.undo()
    assert np.array_equal(read_image(target), old)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.png"]


# --- capture set ----------------------------------------------------------------------------


def test_capture_set_round_trip(tmp_path: Path) -> None:
    white = _images(1, names=(*REQUIRED, "black"))
    screen = _images(2, names=(*REQUIRED, "black", "chessboard"))
    white["gray"][0, 0] = 255  # some saturation to report
    written = write_capture_set(tmp_path / "set", _rig(), white, screen)
    assert (tmp_path / "set" / "rig.toml") in written
    cs = read_capture_set(tmp_path / "set")
    assert cs.rig == _rig()
    assert set(cs.white) == set(cs.screen) == {*REQUIRED, "black"}  # no primaries alone here
    assert cs.has_black and cs.size == (W, H)
    resp = parse_response("srgb")
    for name in REQUIRED:
        lin = cs.screen[name]
        assert lin.dtype == np.float32 and lin.shape == (H, W, 3)
        assert lin == pytest.approx(resp.decode(screen[name] / 255.0), abs=1e-6)
        assert cs.saturated("screen", name) == pytest.approx(np.mean(screen[name] == 255))
    assert cs.saturated("white", "gray") >= 1 / (H * W * 3)
    assert [p.name for p in cs.extra["screen"]] == ["chessboard.png"]
    assert cs.extra["white"] == []
    assert _no_temp_files(tmp_path)


def test_capture_set_16bit_and_npy(tmp_path: Path) -> None:
    white = _images(3, np.uint16)
    screen = {n: (img / 65535.0).astype(np.float32) for n, img in _images(4, np.uint16).items()}
    write_capture_set(tmp_path, _rig(), white, screen)
    assert find_capture(tmp_path, "screen", "gray") == tmp_path / "screen" / "gray.npy"
    cs = read_capture_set(tmp_path)
    assert cs.screen["ramp"] == pytest.approx(screen["ramp"])
    assert not cs.has_black
    assert cs.white["red"] == pytest.approx(
        parse_response("srgb").decode(white["red"] / 65535.0), abs=1e-6
    )


def test_missing_capture_file(tmp_path: Path) -> None:
    write_capture_set(tmp_path, _rig(), _images(1), _images(2))
    (tmp_path / "white" / "gray.png").unlink()
    with pytest.raises(CaptureError) as info:
        read_capture_set(tmp_path)
    assert str(info.value).startswith(
        "not found: white/gray.png - the capture set needs it; "
        "run `viewcomp simulate` or `viewcomp capture`"
    )
    (tmp_path / "rig.toml").unlink()
    with pytest.raises(CaptureError, match=r"not found: rig\.toml"):
        read_capture_set(tmp_path)
    with pytest.raises(CaptureError, match="not found"):
        read_capture_set(tmp_path / "nothing")


def test_wrong_size(tmp_path: Path) -> None:
    write_capture_set(tmp_path, _rig(), _images(1), _images(2))
    write_png(tmp_path / "screen" / "ramp.png", np.zeros((H // 2, W // 2, 3), np.uint8))
    with pytest.raises(CaptureError) as info:
        read_capture_set(tmp_path)
    assert str(info.value) == (
        f"wrong size: screen/ramp.png is {W // 2}x{H // 2}, the projector grid is {W}x{H} "
        "(space = projector)"
    )


def test_camera_space_checks_the_camera_resolution(tmp_path: Path) -> None:
    with pytest.raises(CaptureError, match=r"camera's resolution is 64x32 \(space = camera\)"):
        write_capture_set(tmp_path / "c", _rig("camera"), _images(1), _images(2))
    assert not (tmp_path / "c").exists()


def test_black_in_one_folder_only(tmp_path: Path) -> None:
    write_capture_set(tmp_path, _rig(), _images(1), _images(2))
    write_png(tmp_path / "white" / "black.png", np.zeros((H, W, 3), np.uint8))
    with pytest.raises(CaptureError, match=r"black is optional, but white/black\.png exists"):
        read_capture_set(tmp_path)
    with pytest.raises(ValueError, match="black must be given for both"):
        write_capture_set(tmp_path, _rig(), _images(1, names=(*REQUIRED, "black")), _images(2))


def test_rewrite_removes_stale_variants(tmp_path: Path) -> None:
    write_capture_set(
        tmp_path,
        _rig(),
        _images(1, names=(*REQUIRED, "black")),
        _images(2, names=(*REQUIRED, "black")),
    )
    screen = {n: (img / 255.0).astype(np.float32) for n, img in _images(3).items()}
    write_capture_set(tmp_path, _rig(), _images(4), screen)
    cs = read_capture_set(tmp_path)  # no ambiguity gray.png/gray.npy, no stale black
    assert not cs.has_black
    assert not (tmp_path / "screen" / "gray.png").exists()


def test_ambiguous_capture(tmp_path: Path) -> None:
    write_capture_set(tmp_path, _rig(), _images(1), _images(2))
    write_npy(tmp_path / "white" / "red.npy", np.zeros((H, W, 3), np.float32))
    with pytest.raises(CaptureError, match=r"ambiguous: white/red\.png and white/red\.npy"):
        read_capture_set(tmp_path)


def test_unknown_rig_key_in_capture_set(tmp_path: Path) -> None:
    write_capture_set(tmp_path, _rig(), _images(1), _images(2))
    rig_path = tmp_path / "rig.toml"
    rig_path.write_text(rig_path.read_text().replace("[viewer]", "[viewer]\nheigth = 0.1"))
    with pytest.raises(RigError, match=r'\[viewer\] unknown key "heigth" \(did you mean "height"'):
        read_capture_set(tmp_path)


def test_refuses_to_write_into_a_foreign_folder(tmp_path: Path) -> None:
    (tmp_path / "notes.txt").write_text("mine")
    with pytest.raises(CaptureError, match=r"not empty and has no rig\.toml"):
        write_capture_set(tmp_path, _rig(), _images(1), _images(2))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt"]
    with pytest.raises(ValueError, match="lacks ramp"):
        write_capture_set(tmp_path / "new", _rig(), _images(1, names=REQUIRED[:4]), _images(2))
