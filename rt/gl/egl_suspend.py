"""Releasing the EGL context current on this thread while a window's GLX context is used."""

from __future__ import annotations

import ctypes
import logging
from typing import Any

from viewcomp.rt.gl.context import libegl

log = logging.getLogger(__name__)


class EglSuspend:
    """Releases an EGL context current on this thread, and makes it current again later.

    A GLX context (the window's) cannot become current while an EGL one is (X error
    BadAccess, fatal): a process that also renders headless through
    :func:`viewcomp.rt.gl.context.create_context` on this thread gets its context back after
    playback.
    """

    _EGL_DRAW, _EGL_READ = 0x3059, 0x305A

    def __init__(self) -> None:
        self._saved: tuple[int, int, int, int] | None = None
        self._lib: Any = None
        try:
            lib = libegl()
        except OSError:
            return
        for name in ("eglGetCurrentDisplay", "eglGetCurrentContext", "eglGetCurrentSurface"):
            getattr(lib, name).restype = ctypes.c_void_p
        lib.eglGetCurrentSurface.argtypes = [ctypes.c_int]
        lib.eglMakeCurrent.argtypes = [ctypes.c_void_p] * 4
        context = lib.eglGetCurrentContext()
        if not context:
            return
        display = lib.eglGetCurrentDisplay()
        draw = lib.eglGetCurrentSurface(self._EGL_DRAW)
        read = lib.eglGetCurrentSurface(self._EGL_READ)
        lib.eglMakeCurrent(display, None, None, None)
        self._lib, self._saved = lib, (display, draw, read, context)

    def restore(self) -> None:
        """Make the released context current again (idempotent)."""
        if self._saved is not None:
            if not self._lib.eglMakeCurrent(*self._saved):  # e.g. destroyed meanwhile
                log.debug("could not make the previous EGL context current again")
            self._saved = None
