"""Locking a camera's automatic modes before a capture, through the controls of
:mod:`viewcomp.calib.hw.interface`: automatic exposure, white balance and focus off (read back),
the white balance pinned where it is, the gain at its base (1), and an exposure set when one is
given. A capture whose brightness or colour drifts between patterns cannot be calibrated, so a
failed lock of exposure or white balance is an error unless the user allows it.
"""

from __future__ import annotations

from viewcomp.calib.hw.interface import Camera, DeviceError

ALLOW = "or pass --allow-auto to capture anyway"

_WHY = {
    "auto_exposure": (
        "automatic exposure",
        "brightness would drift between captures; switch it off in the camera's own tool "
        "(v4l2-ctl, guvcview, the vendor's viewer)",
    ),
    "auto_white_balance": (
        "automatic white balance",
        "colours would drift between captures; switch it off in the camera's own tool "
        "(v4l2-ctl, guvcview, the vendor's viewer)",
    ),
}


def lock_controls(
    camera: Camera, allow_auto: bool = False, exposure: float | None = None
) -> list[str]:
    """Lock ``camera`` for a capture (see the module doc); returns warnings for the user.

    Args:
        allow_auto: a failed lock of automatic exposure or white balance is a warning
            instead of an error.
        exposure: seconds to set (read back and reported); None keeps the camera's.

    Raises:
        DeviceError: an automatic mode could not be switched off (without ``allow_auto``), or
            ``exposure`` could not be set; the message names the camera and the fix.
    """
    have = camera.controls()
    warnings: list[str] = []
    for control, (what, fix) in _WHY.items():
        if control not in have:
            continue
        problem = _switch_off(camera, control)
        if problem is None:
            continue
        msg = f"{camera.name}: {what} could not be switched off ({problem}): {fix}"
        if not allow_auto:
            raise DeviceError(f"{msg}, {ALLOW}")
        warnings.append(f"{msg} (--allow-auto: going on)")
    if "autofocus" in have:
        problem = _switch_off(camera, "autofocus")
        if problem is not None:
            warnings.append(
                f"{camera.name}: autofocus could not be switched off ({problem}); fine for a "
                "fixed-focus camera, otherwise switch it off in the camera's own tool"
            )
    if "white_balance" in have and "auto_white_balance" in have:
        try:
            camera.set("white_balance", camera.get("white_balance"))
        except DeviceError as e:
            warnings.append(f"{camera.name}: the white balance could not be pinned ({e})")
    if "gain" in have:
        try:
            got = camera.set("gain", 1.0)
        except DeviceError as e:
            warnings.append(f"{camera.name}: the gain could not be set to its base, 1 ({e})")
        else:
            if abs(got - 1.0) > 0.01:
                warnings.append(
                    f"{camera.name}: asked for gain 1 (the sensor's base), it reports {got:.4g}: "
                    "more noise than needed"
                )
    if exposure is not None:
        if "exposure" not in have:
            raise DeviceError(
                f"{camera.name} has no exposure control: capture without --exposure (its own "
                "exposure is kept), or use a backend that sets it"
            )
        got = camera.set("exposure", exposure)
        if abs(got - exposure) > 0.05 * exposure:
            warnings.append(
                f"{camera.name}: asked for exposure {exposure:.6g} s, it reports {got:.6g} s "
                "(the driver's steps or range): captured at that"
            )
    return warnings


def _switch_off(camera: Camera, control: str) -> str | None:
    """Set ``control`` to 0 and read it back; None when it is off, else why not."""
    try:
        got = camera.set(control, 0.0)
    except DeviceError as e:
        return f"the driver refuses: {e}"
    if got != 0:
        return f"it reads back {got:g}"
    return None
