"""A private X server (Xvfb) for tests and headless runs of the player and of mpv.

``with Xvfb((1280, 720)) as x:`` starts ``Xvfb -displayfd`` (it picks a free display
number and reports it), sets ``DISPLAY`` for this process for the duration, and stops the
server afterwards. Mesa gives GLX contexts on it (llvmpipe). Debian package: xvfb.
"""

from __future__ import annotations

import os
import select
import shutil
import subprocess
from typing import IO

from viewcomp.calib.errors import XvfbError


def xvfb_available() -> bool:
    """True when the ``Xvfb`` executable is on PATH."""
    return shutil.which("Xvfb") is not None


class Xvfb:
    """An Xvfb server with one screen of ``size`` (W, H) and ``depth`` bits.

    Attributes after :meth:`start`: ``display`` (e.g. ``":3"``), ``process``.
    """

    def __init__(self, size: tuple[int, int] = (1280, 720), depth: int = 24) -> None:
        self.size = size
        self.depth = depth
        self.display = ""
        self.process: subprocess.Popen[bytes] | None = None
        self._old_display: str | None = None

    def start(self, timeout: float = 10.0) -> str:
        """Start the server and return its display name.

        Raises:
            XvfbError: not installed, or no display number reported within ``timeout``.
        """
        exe = shutil.which("Xvfb")
        if exe is None:
            raise XvfbError("Xvfb is not installed (Debian package xvfb)")
        r, w = os.pipe()
        w_, h_ = self.size
        try:
            self.process = subprocess.Popen(
                [
                    exe,
                    "-displayfd",
                    str(w),
                    "-screen",
                    "0",
                    f"{w_}x{h_}x{self.depth}",
                    "-nolisten",
                    "tcp",
                    "-noreset",
                ],
                pass_fds=(w,),
                stdout=subprocess.DEVNULL,
                stderr=subprocess.PIPE,
            )
        finally:
            os.close(w)
        try:
            number = self._read_number(r, timeout)
        finally:
            os.close(r)
        self.display = f":{number}"
        return self.display

    def _read_number(self, fd: int, timeout: float) -> int:
        data = b""
        while not data.endswith(b"\n"):
            ready, _, _ = select.select([fd], [], [], timeout)
            chunk = os.read(fd, 64) if ready else b""
            if not chunk:
                err = self._stderr()
                self.stop()
                raise XvfbError(f"Xvfb did not report a display within {timeout:g} s: {err}")
            data += chunk
        return int(data.strip())

    def _stderr(self) -> str:
        p = self.process
        if p is None or p.poll() is None or p.stderr is None:
            return "(still running)"
        return _tail(p.stderr)

    def stop(self) -> None:
        """Stop the server (idempotent)."""
        p, self.process = self.process, None
        if p is not None and p.poll() is None:
            p.terminate()
            try:
                p.wait(timeout=5.0)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        if p is not None and p.stderr is not None:
            p.stderr.close()

    def __enter__(self) -> Xvfb:
        self.start()
        self._old_display = os.environ.get("DISPLAY")
        os.environ["DISPLAY"] = self.display
        return self

    def __exit__(self, *exc: object) -> None:
        if self._old_display is None:
            os.environ.pop("DISPLAY", None)
        else:
            os.environ["DISPLAY"] = self._old_display
        self.stop()


def _tail(stream: IO[bytes], limit: int = 2000) -> str:
    return stream.read()[-limit:].decode(errors="replace").strip()
