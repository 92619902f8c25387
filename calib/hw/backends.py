"""Camera backends by name, and the plug-in point for any other.

``--camera-backend NAME`` picks one of :data:`BUILTIN` (``--camera SPEC`` is passed to it), or
``module:factory`` loads ``factory`` from an importable Python module and calls
``factory(spec: str)``, which must return an object implementing
:class:`~viewcomp.calib.hw.interface.Camera` (controls in the units of ``CONTROLS``, frames
timestamped on ``time.monotonic``): a vendor SDK plugs in without touching viewcomp. The
optional packages (``gphoto2``, ``harvesters``) are imported only when their backend is used.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable

from viewcomp.calib.hw.interface import Camera, Clock, DeviceError

#: Built-in backends: name -> what ``--camera SPEC`` is for it.
BUILTIN: dict[str, str] = {
    "opencv": "an OpenCV camera index (0 is the first)",
    "gphoto2": "a gphoto2 camera model or port (empty: the first camera found)",
    "genicam": "PRODUCER.cti[#SERIAL]: a GenTL producer file and optionally a serial number",
}

#: What a Camera must have (the attributes of the protocol).
CAMERA_ATTRIBUTES = ("name", "resolution", "channels", "controls", "get", "set", "grab", "close")


def open_camera(
    backend: str, spec: str, clock: Clock, size: tuple[int, int] | None = None
) -> Camera:
    """The camera ``spec`` of ``backend`` (a name of :data:`BUILTIN` or ``module:factory``);
    ``size`` (width, height) is asked of the OpenCV backend only.

    Raises:
        DeviceError: unknown backend, a missing optional package, a plug-in that cannot be
            loaded or does not return a Camera; the message names it and the fix.
    """
    if backend == "opencv":
        from viewcomp.calib.hw.opencv_camera import OpenCVCamera

        try:
            index = int(spec)
        except ValueError:
            raise DeviceError(
                f"--camera {spec!r}: the OpenCV backend takes a camera index (0 is the first)"
            ) from None
        return OpenCVCamera(index, size=size, clock=clock)
    if backend == "gphoto2":
        from viewcomp.calib.hw.gphoto2_camera import GPhoto2Camera

        return GPhoto2Camera(spec, clock=clock)
    if backend == "genicam":
        from viewcomp.calib.hw.genicam_camera import GenICamCamera

        return GenICamCamera(spec, clock=clock)
    if ":" in backend:
        return check_camera(load_factory(backend)(spec), backend)
    names = ", ".join(BUILTIN)
    raise DeviceError(
        f"unknown --camera-backend {backend!r}: use one of {names}, or module:factory for a "
        "plug-in (a function factory(spec) -> Camera in an importable module)"
    )


def load_factory(target: str) -> Callable[[str], object]:
    """``module:factory`` -> the callable. Raises DeviceError naming what is missing."""
    module_name, _, attr = target.partition(":")
    if not module_name or not attr:
        raise DeviceError(
            f"--camera-backend {target!r}: a plug-in is written module:factory (e.g. "
            "mycams.vendor:open_camera)"
        )
    try:
        module = importlib.import_module(module_name)
    except ImportError as e:
        raise DeviceError(
            f"--camera-backend {target}: cannot import {module_name!r} ({e}): install it, or "
            "put its folder on PYTHONPATH"
        ) from e
    factory = getattr(module, attr, None)
    if not callable(factory):
        raise DeviceError(
            f"--camera-backend {target}: {module_name} has no function {attr!r} (give "
            "module:factory with factory(spec: str) -> Camera)"
        )
    return factory


def check_camera(camera: object, source: str) -> Camera:
    """``camera`` when it has every attribute of the Camera protocol, else DeviceError."""
    missing = [a for a in CAMERA_ATTRIBUTES if not hasattr(camera, a)]
    if missing:
        raise DeviceError(
            f"--camera-backend {source} returned a {type(camera).__name__} without "
            f"{', '.join(missing)}: a plug-in camera implements "
            "viewcomp.calib.hw.interface.Camera (see docs/INTERFACES.md)"
        )
    return camera  # type: ignore[return-value]
