"""Rectification of an emulated webcam's captures (0.6 camera px per projector px, MJPEG,
demosaicking, sharpening): the frame's edge zone and the reconstruction filter keep the
per-pixel ratio of the real screen to the white one true up to the frame's edge.

The truth is the emulator's own physics (what an ideal camera sees on the projector grid), not
anything the rectification computes.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from viewcomp.calib.emu.emulator import open_emulator
from viewcomp.calib.eval.hardware import emulated_capture
from viewcomp.calib.geo.rectify import rectify_capture_set
from viewcomp.calib.io.captureset import read_capture_set
from viewcomp.calib.sim.simulate import projector_patterns

SIZE = (240, 120)


@pytest.fixture(scope="module")
def webcam(tmp_path_factory: pytest.TempPathFactory):
    emu = open_emulator("webcam", "magenta", seed=3, projector_size=SIZE)
    out = Path(tmp_path_factory.mktemp("webcam")) / "caps"
    emulated_capture(emu, out, hdr=False, frames=2)
    rect, stats = rectify_capture_set(read_capture_set(out))
    truth = emu.truth
    cam = np.asarray(truth.rig.camera.position, np.float64)
    pats = projector_patterns(SIZE, True)
    ideal = {
        s: {k: truth.observe_linear(s, pats[k], cam) for k in ("gray", "black")}
        for s in ("white", "screen")
    }
    return rect, stats, ideal


def _ratio(white: dict, screen: dict) -> np.ndarray:
    """The real screen's gray over the white screen's, black removed: (H, W, 3)."""
    return (screen["gray"] - screen["black"]) / np.maximum(white["gray"] - white["black"], 1e-6)


@pytest.mark.slow
def test_the_webcam_edge_zone_is_measured_and_the_camera_filtered(webcam) -> None:
    _, stats, _ = webcam
    assert 0.5 < stats["density_camera_px"] < 0.7
    assert stats["reconstruction_sigma_px"] > 0
    # the webcam spreads its frame's edge over several projector px (MJPEG chroma and all)
    assert min(stats["edge_zone_px"].values()) >= 3, stats["edge_zone_px"]


@pytest.mark.slow
def test_the_ratio_is_true_up_to_the_frame_edge(webcam) -> None:
    rect, _, ideal = webcam
    got = _ratio(rect.white, rect.screen)
    true = _ratio(ideal["white"], ideal["screen"])
    q = got / true
    q = q / np.median(q.reshape(-1, 3), axis=0)  # the camera's white balance and response
    h, w = q.shape[:2]
    ring = np.zeros((h, w), bool)
    ring[:3] = ring[-3:] = True
    ring[:, :3] = ring[:, -3:] = True
    corners = np.zeros((h, w), bool)
    for rows in (slice(0, 6), slice(h - 6, h)):
        for cols in (slice(0, 6), slice(w - 6, w)):
            corners[rows, cols] = True
    # red and blue (the magenta screen's own channels; its green is a few codes): with one
    # line of edge filled and no reconstruction filter, the outer three lines read 12 % low
    # in red
    for c in (0, 2):
        edge = float(np.mean(q[ring, c]))
        corner = float(np.mean(q[corners, c]))
        assert abs(edge - 1.0) < 0.06, (c, edge)
        assert abs(corner - 1.0) < 0.1, (c, corner)
