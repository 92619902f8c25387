"""The error for an optional package that a camera backend needs and cannot import."""

from __future__ import annotations

from viewcomp.calib.hw.interface import DeviceError


def missing_package(package: str, backend: str, error: ImportError) -> DeviceError:
    """A DeviceError naming ``package``, the ``backend`` that needs it and the fix."""
    return DeviceError(
        f"the {backend} camera backend needs the Python package {package!r}, which cannot be "
        f"imported ({error}): pip install {package} (into viewcomp's environment), or choose "
        "another --camera-backend"
    )
