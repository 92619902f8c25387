"""Calibration patterns (Table 1, chessboard, Gray code) and the evaluation's test images."""

from __future__ import annotations

import socket
from pathlib import Path

import cv2
import numpy as np
import pytest

from viewcomp.calib.eval.testimages import natural_images, procedural_images, uniform
from viewcomp.calib.io.imageio import read_image
from viewcomp.calib.io.patterns import (
    chessboard,
    graycode_patterns,
    ramp_levels,
    table1_patterns,
    write_patterns,
)


def test_table1_colours() -> None:
    p = table1_patterns(64, 8)
    assert list(p) == ["red", "green", "blue", "gray", "ramp", "black"]
    for name, rgb in {
        "red": (130, 110, 110),
        "green": (110, 130, 110),
        "blue": (110, 110, 130),
        "gray": (110, 110, 110),
        "black": (0, 0, 0),
    }.items():
        assert p[name].dtype == np.uint8 and p[name].shape == (8, 64, 3)
        assert (p[name] == rgb).all()


def test_a_camera_capture_raises_the_colour_patterns_further() -> None:
    """`capture` on a device shows the colour patterns at CAMERA_COLOUR_LEVEL in their own
    channel (gray, ramp and black as Table 1); projector-space sets keep Table 1's 130."""
    from viewcomp.calib.hw.plan import capture_plan
    from viewcomp.calib.io.patterns import CAMERA_COLOUR_LEVEL

    p = table1_patterns(64, 8, 200)
    assert (p["red"] == (200, 110, 110)).all() and (p["blue"] == (110, 110, 200)).all()
    assert (p["gray"] == 110).all() and np.array_equal(p["ramp"], table1_patterns(64, 8)["ramp"])
    for bad in (110, 256):
        with pytest.raises(ValueError, match="colour_level"):
            table1_patterns(64, 8, bad)
    shown = {(s.sub, s.name): s.pattern[0, 0].tolist() for s in capture_plan(320, 160)}
    for sub in ("white", "screen"):
        assert shown[(sub, "green")] == [110, CAMERA_COLOUR_LEVEL, 110]
        assert shown[(sub, "gray")] == [110, 110, 110]


@pytest.mark.parametrize("w", [2, 3, 7, 256, 640, 1920])
def test_ramp_formula(w: int) -> None:
    ramp = table1_patterns(w, 3)["ramp"]
    u = np.arange(w)
    expected = np.floor(255 * u / (w - 1) + 0.5).astype(np.uint8)  # round(255 u / (w - 1))
    for row in range(3):
        for c in range(3):
            assert np.array_equal(ramp[row, :, c], expected)
    assert ramp[0, 0, 0] == 0 and ramp[0, -1, 0] == 255


def test_ramp_matches_round_half_even_at_640() -> None:
    # no column of a 640-wide ramp is a tie, so every rounding convention agrees
    assert np.array_equal(ramp_levels(640), np.round(255 * np.arange(640) / 639).astype(np.uint8))
    assert ramp_levels(7)[1] == 43  # 255/6 = 42.5 rounds up


def test_chessboard_is_found_by_opencv_at_the_returned_corners() -> None:
    img, corners = chessboard(640, 320)
    assert img.shape == (320, 640, 3) and img.dtype == np.uint8
    assert corners.shape == (8 * 5, 2)
    assert (img[0] == 255).all() and (img[:, 0] == 255).all()  # white margin
    ok, found = cv2.findChessboardCorners(img[:, :, 0], (8, 5))
    assert ok
    found = found.reshape(-1, 2)
    if np.linalg.norm(found[0] - corners[0]) > np.linalg.norm(found[-1] - corners[0]):
        found = found[::-1]  # OpenCV may list a board from either end
    assert found == pytest.approx(corners, abs=0.5)


def test_chessboard_too_small() -> None:
    with pytest.raises(ValueError, match="too small"):
        chessboard(20, 10)


def test_graycode_patterns() -> None:
    planes, white, black = graycode_patterns(64, 32)
    assert len(planes) == 2 * (6 + 5)  # log2(64) column bits + log2(32) row bits, with inverses
    for p in planes:
        assert p.shape == (32, 64, 3) and p.dtype == np.uint8
        assert set(np.unique(p)) <= {0, 255}
    assert (white == 255).all() and (black == 0).all()
    assert np.array_equal(planes[0], 255 - planes[1])


def test_write_patterns(tmp_path: Path) -> None:
    paths = write_patterns(tmp_path / "out", 64, 32)
    names = [p.name for p in paths]
    assert names[:7] == [
        "red.png",
        "green.png",
        "blue.png",
        "gray.png",
        "ramp.png",
        "black.png",
        "chessboard.png",
    ]
    assert "graycode_00.png" in names and "graycode_21.png" in names
    assert "graycode_white.png" in names and "graycode_black.png" in names
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == sorted(names)
    ramp = read_image(tmp_path / "out" / "ramp.png")
    assert np.array_equal(ramp, table1_patterns(64, 32)["ramp"])


def test_natural_images_never_touch_the_network(monkeypatch: pytest.MonkeyPatch) -> None:
    def no_network(*args: object, **kwargs: object) -> None:
        raise OSError("network is unplugged in this test")

    monkeypatch.setattr(socket.socket, "connect", no_network)
    monkeypatch.setattr(socket, "create_connection", no_network)
    imgs = natural_images(64, 32)
    assert len(imgs) >= 3
    for img in imgs.values():
        assert img.shape == (32, 64, 3) and img.dtype == np.uint8
        assert img.std() > 10  # not flat
    again = natural_images(64, 32)
    assert list(imgs) == list(again)
    assert all(np.array_equal(imgs[k], again[k]) for k in imgs)


def test_procedural_images_are_deterministic() -> None:
    a, b = procedural_images(48, 32), procedural_images(48, 32)
    assert list(a) == ["landscape", "still_life", "portrait"]
    for name in a:
        assert a[name].shape == (32, 48, 3) and a[name].dtype == np.uint8
        assert np.array_equal(a[name], b[name])
        assert a[name].std() > 10


def test_uniform() -> None:
    img = uniform((100, 50, 50), 5, 4)
    assert img.shape == (4, 5, 3) and (img == (100, 50, 50)).all()
    with pytest.raises(ValueError, match=r"0\.\.255"):
        uniform((300, 0, 0), 5, 4)
