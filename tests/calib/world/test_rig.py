"""rig.toml: defaults, round trips, projection conventions, refusals."""

from __future__ import annotations

import copy
import math
import tomllib
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from viewcomp.calib.world.rig import (
    Camera,
    CaptureSpec,
    Device,
    Rig,
    RigError,
    Viewer,
    default_rig,
    load_rig,
    rig_from_dict,
    rig_to_toml,
)

EXAMPLE = """
[projector]
resolution = [640, 320]
position = [0.0, -0.03, 0.5]
look_at = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
fov_y = 20.0

[camera]
resolution = [1280, 720]
position = [0.0, 0.035, 0.5]
look_at = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
fov_y = 30.0
response = "srgb"

[viewer]
distance = 0.5
height = 0.035

[capture]
space = "projector"
"""


def _example() -> dict[str, Any]:
    return tomllib.loads(EXAMPLE)


def _front_device(**kw: Any) -> Device:
    args: dict[str, Any] = {
        "resolution": (640, 320),
        "position": (0.0, 0.0, 0.5),
        "look_at": (0.0, 0.0, 0.0),
        "up": (0.0, 1.0, 0.0),
        "fov_y": 20.0,
    }
    args.update(kw)
    return Device(**args)


def test_default_rig_is_the_interfaces_example() -> None:
    assert rig_from_dict(_example()) == default_rig()
    rig = default_rig()
    assert rig.projector.resolution == (640, 320)
    assert rig.camera.response == "srgb"
    assert rig.viewer.height == 0.035
    assert rig.capture.space == "projector"


def test_toml_round_trip(tmp_path: Path) -> None:
    rig = default_rig()
    fancy = replace(
        rig,
        projector=replace(rig.projector, principal_point=(320.25, 150.0)),
        camera=replace(rig.camera, distortion=(0.1, -0.02, 0.001, 0.0, 1e-5), response=2.2),
        capture=CaptureSpec(space="camera"),
    )
    # a response table, as `capture --hdr` writes one for an S-shaped camera curve
    table = tuple(float(f"{v:.7g}") for v in np.linspace(0.0, 1.0, 256) ** 2.1)
    tabled = replace(rig, camera=replace(rig.camera, response=table))
    for r in (rig, fancy, tabled):
        path = tmp_path / "rig.toml"
        path.write_text(rig_to_toml(r))
        assert load_rig(path) == r
    text = rig_to_toml(tabled)
    assert max(len(line) for line in text.splitlines()) < 120  # 8 entries a line
    bad = text.replace("1.0,\n]", "0.9,\n]")
    assert bad != text
    path.write_text(bad)
    with pytest.raises(RigError, match="response: a camera response table goes from 0"):
        load_rig(path)


def test_viewer_height_defaults_to_camera_y() -> None:
    d = _example()
    del d["viewer"]["height"]
    rig = rig_from_dict(d)
    assert rig.viewer.height == pytest.approx(0.035)
    eye = rig.viewer.eye(90.0)
    assert eye == pytest.approx([0.0, 0.035, 0.5], abs=1e-12)
    # theta < 90 is the audience's right (+x)
    assert rig.viewer.eye(60.0)[0] > 0


def test_intrinsics() -> None:
    dev = _front_device()
    k = dev.intrinsics()
    f = 160.0 / math.tan(math.radians(10.0))
    assert k == pytest.approx(np.array([[f, 0, 319.5], [0, f, 159.5], [0, 0, 1]]))
    assert replace(dev, principal_point=(300.0, 100.0)).intrinsics()[:2, 2] == pytest.approx(
        [300.0, 100.0]
    )


def test_pose_is_a_rotation_and_maps_position_to_origin() -> None:
    dev = default_rig().camera
    rot, t = dev.pose()
    assert rot @ rot.T == pytest.approx(np.eye(3), abs=1e-12)
    assert np.linalg.det(rot) == pytest.approx(1.0)
    assert rot @ np.array(dev.position) + t == pytest.approx(np.zeros(3), abs=1e-12)


def test_projection_conventions() -> None:
    dev = _front_device()
    cx, cy = dev.principal()
    centre = dev.project(np.array([0.0, 0.0, 0.0]))
    assert centre == pytest.approx([cx, cy])
    right = dev.project(np.array([0.1, 0.0, 0.0]))
    above = dev.project(np.array([0.0, 0.1, 0.0]))
    assert right[0] > cx and right[1] == pytest.approx(cy)  # world +x is image right
    assert above[1] < cy and above[0] == pytest.approx(cx)  # world +y is image up (v smaller)
    # pinhole: u = cx + f X / Z
    assert right[0] == pytest.approx(cx + dev.focal() * 0.1 / 0.5)


def test_points_behind_project_to_nan() -> None:
    uv = _front_device().project(np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]]))
    assert np.isnan(uv[0]).all() and np.isfinite(uv[1]).all()


@pytest.mark.parametrize("distortion", [None, (0.05, -0.01, 0.001, -0.0005, 0.002)])
def test_pixel_rays_round_trip(distortion: tuple[float, ...] | None) -> None:
    dev = replace(default_rig().projector, resolution=(64, 32), distortion=distortion)
    rays = dev.pixel_rays()
    assert rays.shape == (32, 64, 3)
    assert np.linalg.norm(rays, axis=-1) == pytest.approx(np.ones((32, 64)))
    uv = dev.project(np.array(dev.position) + rays)
    vv, uu = np.mgrid[0:32, 0:64]
    assert uv[..., 0] == pytest.approx(uu, abs=1e-6)
    assert uv[..., 1] == pytest.approx(vv, abs=1e-6)


def test_pixel_rays_on_a_resampled_grid() -> None:
    dev = _front_device(resolution=(64, 32))
    half = dev.pixel_rays(16, 32)
    uv = dev.project(np.array(dev.position) + half)
    assert uv[0, 0] == pytest.approx([0.5, 0.5])  # centre of the 2x2 block of full pixels
    assert dev.pixel_rays(32, 64) == pytest.approx(dev.pixel_rays())


def test_one_ray_plane_intersection_for_grids_and_points() -> None:
    from viewcomp.calib.world.geometry import (
        GeometryError,
        meet_screen,
        screen_points,
        screen_points_at,
    )

    dev = replace(default_rig().projector, resolution=(64, 32))
    grid = screen_points(dev)
    vv, uu = np.mgrid[0:32, 0:64]
    at = screen_points_at(dev, np.stack([uu, vv], -1).astype(float))
    assert np.abs(at - grid).max() < 1e-12 and np.all(grid[..., 2] == 0.0)
    # each point lies on its pixel's ray: it projects back to the pixel
    assert dev.project(at) == pytest.approx(np.stack([uu, vv], -1), abs=1e-6)
    origin = np.array([0.0, 0.0, 1.0])
    with pytest.raises(GeometryError, match=r"camera pixels miss .*\[camera\] position"):
        meet_screen(origin, np.array([[0.0, 0.0, 1.0]]), "camera")  # away from the screen
    with pytest.raises(GeometryError, match="projector"):
        meet_screen(origin, np.array([[1.0, 0.0, 0.0]]), "projector")  # parallel to it


def test_dataclass_defaults() -> None:
    cam = Camera(
        resolution=(4, 2),
        position=(0.0, 0.0, 1.0),
        look_at=(0.0, 0.0, 0.0),
        up=(0.0, 1.0, 0.0),
        fov_y=40.0,
        response="linear",
    )
    assert cam.principal() == (1.5, 0.5)
    rig = Rig(
        projector=cam,
        camera=cam,
        viewer=Viewer(distance=1.0),
        capture=CaptureSpec(space="projector"),
    )
    assert rig.viewer.height == 0.0


def _mutate(path: tuple[str, ...], value: Any) -> dict[str, Any]:
    d = copy.deepcopy(_example())
    node = d
    for key in path[:-1]:
        node = node[key]
    if value is _DELETE:
        del node[path[-1]]
    else:
        node[path[-1]] = value
    return d


_DELETE = object()


@pytest.mark.parametrize(
    ("path", "value", "expected"),
    [
        (
            ("projector", "resolution"),
            [640],
            "rig.toml: [projector] resolution must be two positive integers [width, height], "
            "got [640]",
        ),
        (("projector", "resolution"), [640.0, 320.0], "two positive integers"),
        (("camera", "resolution"), [0, 720], "two positive integers"),
        (("projector", "position"), [0.0, 0.0], "[projector] position must be three numbers"),
        (("camera", "up"), ["a", 1, 0], "[camera] up must be three numbers"),
        (("camera", "up"), [0.0, 0.07, 1.0], "[camera] up must not be parallel"),
        (("camera", "look_at"), [0.0, 0.035, 0.5], "look_at must differ from position"),
        (("projector", "fov_y"), 180.0, "[projector] fov_y must be a number of degrees"),
        (("projector", "fov_y"), "20", "fov_y"),
        (("camera", "response"), "log", "[camera] response: unknown camera response 'log'"),
        (("camera", "distortion"), [0.1, 0.2], "distortion must be five numbers"),
        (("projector", "principal_point"), [1, 2, 3], "principal_point must be two numbers"),
        (("viewer", "distance"), -1.0, "[viewer] distance must be a positive number"),
        (("viewer", "height"), "high", "[viewer] height must be a number"),
        (("capture", "space"), "world", '[capture] space must be "projector" or "camera"'),
        (("projector", "fovy"), 20.0, '[projector] unknown key "fovy" (did you mean "fov_y"?)'),
        (("viewer", "distanse"), 0.5, 'unknown key "distanse"'),
        (("projecter",), {}, "unknown section [projecter]"),
        (("camera", "fov_y"), _DELETE, "[camera] missing key fov_y"),
        (("capture",), _DELETE, "missing section [capture]"),
        (("viewer",), 3, "[viewer] must be a table"),
    ],
)
def test_rig_errors_name_file_key_and_expectation(
    path: tuple[str, ...], value: Any, expected: str
) -> None:
    with pytest.raises(RigError) as info:
        rig_from_dict(_mutate(path, value))
    assert expected in str(info.value)
    assert str(info.value).startswith("rig.toml: ")


def test_load_rig_errors_name_the_file(tmp_path: Path) -> None:
    missing = tmp_path / "nope" / "rig.toml"
    with pytest.raises(RigError, match="not found"):
        load_rig(missing)
    bad = tmp_path / "rig.toml"
    bad.write_text("[projector\nresolution = 1")
    with pytest.raises(RigError, match="invalid TOML") as info:
        load_rig(bad)
    assert str(bad) in str(info.value)
    bad.write_text(EXAMPLE.replace("fov_y = 20.0", "fov_y = 20.0\nfoo = 1"))
    with pytest.raises(RigError, match=r'rig\.toml: \[projector\] unknown key "foo"'):
        load_rig(bad)
    assert isinstance(RigError("x"), ValueError)
