"""An X server's display output switched off and on through RandR, as a projector switched off
(or a cable pulled) and back looks to the X clients: the CRTC disabled, then set again to its
mode and output. Xvfb's one output ("screen") supports it; the X clients (glfw) get the real
RandR notifications. libX11 and libXrandr through ctypes (Debian: libx11-6, libxrandr2).
"""

from __future__ import annotations

import ctypes
from types import TracebackType

_ulong = ctypes.c_ulong


class _Resources(ctypes.Structure):
    _fields_ = [
        ("timestamp", _ulong),
        ("config_timestamp", _ulong),
        ("ncrtc", ctypes.c_int),
        ("crtcs", ctypes.POINTER(_ulong)),
        ("noutput", ctypes.c_int),
        ("outputs", ctypes.POINTER(_ulong)),
        ("nmode", ctypes.c_int),
        ("modes", ctypes.c_void_p),
    ]


class _CrtcInfo(ctypes.Structure):
    _fields_ = [
        ("timestamp", _ulong),
        ("x", ctypes.c_int),
        ("y", ctypes.c_int),
        ("width", ctypes.c_uint),
        ("height", ctypes.c_uint),
        ("mode", _ulong),
        ("rotation", ctypes.c_ushort),
        ("noutput", ctypes.c_int),
        ("outputs", ctypes.POINTER(_ulong)),
        ("rotations", ctypes.c_ushort),
        ("npossible", ctypes.c_int),
        ("possible", ctypes.POINTER(_ulong)),
    ]


def _libs() -> tuple[ctypes.CDLL, ctypes.CDLL]:
    x11 = ctypes.CDLL("libX11.so.6")
    rr = ctypes.CDLL("libXrandr.so.2")
    x11.XOpenDisplay.restype = ctypes.c_void_p
    x11.XOpenDisplay.argtypes = [ctypes.c_char_p]
    x11.XDefaultRootWindow.restype = _ulong
    x11.XDefaultRootWindow.argtypes = [ctypes.c_void_p]
    x11.XSync.argtypes = [ctypes.c_void_p, ctypes.c_int]
    x11.XCloseDisplay.argtypes = [ctypes.c_void_p]
    rr.XRRGetScreenResources.restype = ctypes.POINTER(_Resources)
    rr.XRRGetScreenResources.argtypes = [ctypes.c_void_p, _ulong]
    rr.XRRFreeScreenResources.argtypes = [ctypes.POINTER(_Resources)]
    rr.XRRGetCrtcInfo.restype = ctypes.POINTER(_CrtcInfo)
    rr.XRRGetCrtcInfo.argtypes = [ctypes.c_void_p, ctypes.POINTER(_Resources), _ulong]
    rr.XRRFreeCrtcInfo.argtypes = [ctypes.POINTER(_CrtcInfo)]
    rr.XRRSetCrtcConfig.restype = ctypes.c_int
    rr.XRRSetCrtcConfig.argtypes = [
        ctypes.c_void_p,
        ctypes.POINTER(_Resources),
        _ulong,
        _ulong,
        ctypes.c_int,
        ctypes.c_int,
        _ulong,
        ctypes.c_ushort,
        ctypes.POINTER(_ulong),
        ctypes.c_int,
    ]
    return x11, rr


class DisplayOutput:
    """The first CRTC of X display ``display`` (e.g. ``":3"``): :meth:`off` disables it (its
    monitor disappears), :meth:`on` restores the mode and output it had when opened."""

    def __init__(self, display: str) -> None:
        self._x11, self._rr = _libs()
        self._dpy = self._x11.XOpenDisplay(display.encode())
        if not self._dpy:
            raise RuntimeError(f"cannot open X display {display}")
        self._root = self._x11.XDefaultRootWindow(self._dpy)
        res = self._rr.XRRGetScreenResources(self._dpy, self._root)
        try:
            self._crtc = int(res.contents.crtcs[0])
            info = self._rr.XRRGetCrtcInfo(self._dpy, res, self._crtc)
            c = info.contents
            self._mode, self._rotation = int(c.mode), int(c.rotation)
            self._x, self._y = int(c.x), int(c.y)
            self._output = int(c.outputs[0])
            self._rr.XRRFreeCrtcInfo(info)
        finally:
            self._rr.XRRFreeScreenResources(res)

    def _set(self, mode: int, outputs: list[int]) -> None:
        res = self._rr.XRRGetScreenResources(self._dpy, self._root)
        try:
            arr = (_ulong * max(len(outputs), 1))(*outputs)
            status = self._rr.XRRSetCrtcConfig(
                self._dpy,
                res,
                self._crtc,
                0,  # CurrentTime
                self._x,
                self._y,
                mode,
                self._rotation if mode else 1,
                arr if outputs else None,
                len(outputs),
            )
            self._x11.XSync(self._dpy, 0)
        finally:
            self._rr.XRRFreeScreenResources(res)
        if status != 0:
            raise RuntimeError(f"RandR refused the CRTC change (status {status})")

    def off(self) -> None:
        """The output disabled: its monitor is gone for every X client."""
        self._set(0, [])

    def on(self) -> None:
        """The output back at the mode it had when opened."""
        self._set(self._mode, [self._output])

    def close(self) -> None:
        if self._dpy:
            self._x11.XCloseDisplay(self._dpy)
            self._dpy = None

    def __enter__(self) -> DisplayOutput:
        return self

    def __exit__(
        self, t: type[BaseException] | None, e: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()
