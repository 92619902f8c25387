"""`viewcomp check-mpv`: does the installed mpv run an exported shader, or reject it?

mpv reads a user shader when it starts playing; one it cannot parse (Debian 12's mpv 0.35
and ``//!PARAM``) or compile is logged as an error of its video output and skipped, and the
video plays uncompensated with exit status 0. :func:`check_mpv` runs the installed mpv on a
tiny still with the shader and :func:`guard_script` (which makes such an error fatal:
exit status 2) and reports what mpv said. Without an X display it starts a private Xvfb
and mpv renders with Mesa's software OpenGL (``--gpu-context=x11egl --gpu-sw``): mpv's
shader parser is the same, the GLSL compiler is Mesa's (a kiosk's driver may be stricter).
"""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from viewcomp.calib.errors import MpvCheckError
from viewcomp.rt.export.mpv import guard_script
from viewcomp.rt.play.xvfb import Xvfb, XvfbError, xvfb_available

# mpv's listing of the GLSL it failed to compile ("[vo/gpu/opengl] [ 12] ...", "... shader
# source:"): context, not the error.
_SOURCE_LINE = re.compile(r"^\[vo[^\]]*\] (?:\[\s*\d+\]|.*source:$|$)")


#: The guard's exit status when mpv could not open any video output (the shader untried).
NO_OUTPUT_STATUS = 3


@dataclass(frozen=True)
class MpvCheck:
    """What mpv did with the shader: ``ok`` when it exited 0 with no error of its video
    output; ``errors`` mpv's error lines; ``version`` its first ``--version`` line;
    ``no_output`` when mpv could not open a video output at all (the guard's exit status 3:
    the shader was never tried, so the check says nothing about it)."""

    ok: bool
    status: int
    errors: list[str]
    version: str
    command: list[str]
    no_output: bool = False


def _still(path: Path) -> None:
    """A 64x32 colour ramp (any picture does: the check is whether mpv takes the shader)."""
    yy, xx = np.mgrid[0:32, 0:64]
    img = np.dstack([xx * 4, yy * 8, 255 - xx * 4]).astype(np.uint8)
    cv2.imwrite(str(path), img)


def check_mpv(
    shader: str | os.PathLike[str], vo: str = "gpu", headless: bool = False, timeout: float = 60.0
) -> MpvCheck:
    """Run the installed mpv (``vo``: ``gpu`` or ``gpu-next``) on a tiny still through
    ``shader`` and the guard script, for one frame: on this X display, or with ``headless``
    or without one on a private Xvfb with software OpenGL.

    Raises:
        MpvCheckError: mpv not installed, the shader file missing, no display and no Xvfb,
            or mpv not finishing within ``timeout`` seconds.
    """
    exe = shutil.which("mpv")
    if exe is None:
        raise MpvCheckError("mpv is not installed; fix: install it (Debian package mpv)")
    shader = Path(shader)
    if not shader.is_file():
        raise MpvCheckError(f"no shader file {shader}; fix: give the file export-mpv wrote")
    version = subprocess.run([exe, "--version"], capture_output=True, text=True, timeout=30)
    first = " ".join((version.stdout.split() or ["mpv", "(unknown version)"])[:2])
    with contextlib.ExitStack() as stack:
        tmp = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="viewcomp-mpv-")))
        still, guard = tmp / "still.png", tmp / "guard.lua"
        _still(still)
        guard.write_text(guard_script(), encoding="utf-8")
        context: list[str] = []
        if headless or not os.environ.get("DISPLAY"):
            if not xvfb_available():
                raise MpvCheckError(
                    "no X display (DISPLAY is not set) and no Xvfb to start "
                    "one; fix: run it on the kiosk's display, or install "
                    "xvfb"
                )
            try:
                stack.enter_context(Xvfb((320, 240)))
            except XvfbError as exc:
                raise MpvCheckError(f"cannot start Xvfb: {exc}") from None
            context = ["--gpu-context=x11egl", "--gpu-sw"]
        cmd = [exe, "--no-config", f"--vo={vo}", *context, f"--glsl-shaders={shader.resolve()}",
               f"--script={guard}", "--frames=1", "--audio=no", "--osc=no",
               "--geometry=64x32", "--msg-level=all=error", str(still)]  # fmt: skip
        try:
            p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
        except subprocess.TimeoutExpired:
            raise MpvCheckError(f"mpv did not finish within {timeout:g} s") from None
    lines = [ln.strip() for ln in (p.stdout + p.stderr).splitlines()]
    errors = [ln for ln in lines if ln.startswith("[vo") and not _SOURCE_LINE.match(ln)]
    no_output = p.returncode == NO_OUTPUT_STATUS
    if no_output:  # the guard's line names the output's failure and what mpv probed
        errors = [ln for ln in lines if "could not open a video output" in ln] or errors
    return MpvCheck(p.returncode == 0 and not errors, p.returncode, errors, first, cmd, no_output)
