"""`viewcomp check-mpv`: does the installed mpv run an exported shader as exported?

mpv reads a user shader when it starts playing; one it cannot parse (Debian 12's mpv 0.35
and ``//!PARAM``) or compile is logged as an error of its video output and skipped, and the
video plays uncompensated with exit status 0. :func:`check_mpv` runs the installed mpv on a
tiny still with the shader and :func:`guard_script` (which makes such an error fatal:
exit status 2) and reports what mpv said. Without an X display it starts a private Xvfb
and mpv renders with Mesa's software OpenGL (``--gpu-context=x11egl --gpu-sw``): mpv's
shader parser is the same, the GLSL compiler is Mesa's (a kiosk's driver may be stricter).

mpv 0.35 also skips, silently, a hook whose ``//!BIND`` textures are missing (a file cut
short). So first :func:`~viewcomp.rt.export.mpv_verify.structure_problems` checks the file
(every bound texture complete, the end marker), and then the still is the export's own
test still (:func:`~viewcomp.rt.export.mpv_verify.check_still`) at the grid's size in a
window of exactly that size, with ``--dither-depth=no``; a small script takes a screenshot
of the window (``screenshot-to-file ... window``: mpv's output after the hook) and its block
means are compared with the check value the export carries (:data:`TOLERANCE`).
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import shutil
import subprocess
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from viewcomp.calib.errors import MpvCheckError
from viewcomp.rt.export.mpv import guard_script
from viewcomp.rt.export.mpv_verify import block_means, check_still, parse_check, structure_problems
from viewcomp.rt.play.xvfb import Xvfb, XvfbError, xvfb_available

# mpv's listing of the GLSL it failed to compile ("[vo/gpu/opengl] [ 12] ...", "... shader
# source:"): context, not the error.
_SOURCE_LINE = re.compile(r"^\[vo[^\]]*\] (?:\[\s*\d+\]|.*source:$|$)")


#: The guard's exit status when mpv could not open any video output (the shader untried).
NO_OUTPUT_STATUS = 3

#: Levels (0..255) by which a block mean of mpv's window may differ from the check value:
#: measured 0.06 at most (Mesa llvmpipe, mpv 0.35, vo=gpu and gpu-next, precision 8/16/32);
#: an uncompensated picture differs by tens of levels.
TOLERANCE = 3.0

# Takes the window's screenshot once the first frame is shown, then quits (status 0; the
# guard quits with 2 or 3 first when mpv rejects the shader or opens no video output).
_SHOT_LUA = """
local shot = %s
local taken = false
mp.register_event("playback-restart", function()
    if taken then return end
    taken = true
    mp.add_timeout(0.5, function()
        mp.commandv("screenshot-to-file", shot, "window")
        mp.commandv("quit", "0")
    end)
end)
"""


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
    expected: np.ndarray | None = None
    measured: np.ndarray | None = None
    problems: list[str] = field(default_factory=list)

    @property
    def picture_ok(self) -> bool | None:
        """Whether mpv's output matches the check value within :data:`TOLERANCE`; None when
        the file has no check value (exported before it) or mpv gave no screenshot."""
        if self.expected is None or self.measured is None:
            return None
        return bool(np.abs(self.measured - self.expected).max() <= TOLERANCE)


def check_mpv(
    shader: str | os.PathLike[str], vo: str = "gpu", headless: bool = False, timeout: float = 60.0
) -> MpvCheck:
    """Check ``shader``'s structure and, when it is whole, run the installed mpv (``vo``:
    ``gpu`` or ``gpu-next``) on the export's test still through it and the guard script,
    screenshot the window (the grid's size) and measure its block means: on this X display,
    or with ``headless`` or without one on a private Xvfb with software OpenGL.

    Returns an :class:`MpvCheck`; with ``problems`` (the file cut short or edited) mpv was
    not run. ``expected``/``measured`` are (4, 4, 3) mean levels (None: no check value in
    the file, or no screenshot).

    Raises:
        MpvCheckError: mpv not installed, the shader file missing or unreadable, no display
            and no Xvfb, or mpv not finishing within ``timeout`` seconds.
    """
    exe = shutil.which("mpv")
    if exe is None:
        raise MpvCheckError("mpv is not installed; fix: install it (Debian package mpv)")
    shader = Path(shader)
    if not shader.is_file():
        raise MpvCheckError(f"no shader file {shader}; fix: give the file export-mpv wrote")
    try:
        text = shader.read_text(encoding="ascii")
    except (OSError, UnicodeDecodeError) as exc:
        raise MpvCheckError(f"cannot read {shader} as an exported shader: {exc}") from None
    version = subprocess.run([exe, "--version"], capture_output=True, text=True, timeout=30)
    first = " ".join((version.stdout.split() or ["mpv", "(unknown version)"])[:2])
    problems = structure_problems(text)
    try:
        check = parse_check(text)
    except ValueError as exc:
        problems.append(str(exc))
        check = None
    if problems:
        return MpvCheck(False, 2, [], first, [], problems=problems)
    grid = check[0] if check is not None else (64, 32)
    with contextlib.ExitStack() as stack:
        tmp = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="viewcomp-mpv-")))
        still, guard, shot = tmp / "still.png", tmp / "guard.lua", tmp / "shot.png"
        cv2.imwrite(str(still), check_still(grid)[..., ::-1])
        guard.write_text(guard_script(), encoding="utf-8")
        (tmp / "shot.lua").write_text(_SHOT_LUA % json.dumps(str(shot)), encoding="utf-8")
        context = _display(stack, headless, grid)
        cmd = [exe, "--no-config", f"--vo={vo}", *context, f"--glsl-shaders={shader.resolve()}",
               f"--script={guard}", f"--script={tmp / 'shot.lua'}", "--pause",
               "--keep-open=always", "--audio=no", "--osc=no", "--osd-level=0", "--border=no",
               "--dither-depth=no", "--screenshot-format=png", f"--geometry={grid[0]}x{grid[1]}",
               "--msg-level=all=error", str(still)]  # fmt: skip
        try:
            p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
        except subprocess.TimeoutExpired:
            raise MpvCheckError(f"mpv did not finish within {timeout:g} s") from None
        picture = cv2.imread(str(shot)) if shot.is_file() else None
    lines = [ln.strip() for ln in (p.stdout + p.stderr).splitlines()]
    errors = [ln for ln in lines if ln.startswith("[vo") and not _SOURCE_LINE.match(ln)]
    no_output = p.returncode == NO_OUTPUT_STATUS
    if no_output:  # the guard's line names the output's failure and what mpv probed
        errors = [ln for ln in lines if "could not open a video output" in ln] or errors
    measured = None
    if picture is not None and picture.shape[1::-1] == tuple(grid):
        measured = block_means(picture[..., ::-1])
    expected = None if check is None else check[1]
    return MpvCheck(p.returncode == 0 and not errors, p.returncode, errors, first, cmd,
                    no_output, expected, measured)  # fmt: skip


def _display(stack: contextlib.ExitStack, headless: bool, grid: tuple[int, int]) -> list[str]:
    """mpv's GPU-context options: none on this X display; with ``headless`` or without a
    display a private Xvfb (at least the grid's size, entered on ``stack``) and Mesa's
    software OpenGL."""
    if not headless and os.environ.get("DISPLAY"):
        return []
    if not xvfb_available():
        raise MpvCheckError(
            "no X display (DISPLAY is not set) and no Xvfb to start one; fix: run it on the "
            "kiosk's display, or install xvfb"
        )
    try:
        stack.enter_context(Xvfb((max(320, grid[0]), max(240, grid[1]))))
    except XvfbError as exc:
        raise MpvCheckError(f"cannot start Xvfb: {exc}") from None
    return ["--gpu-context=x11egl", "--gpu-sw"]
