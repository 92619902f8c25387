"""A DSLR or mirrorless camera through libgphoto2 (the ``gphoto2`` Python package, optional:
imported when this backend is used; ``pip install gphoto2`` brings wheels with libgphoto2).

Each :meth:`GPhoto2Camera.grab` triggers one full capture (``GP_CAPTURE_IMAGE``), downloads
the JPEG from the camera and deletes it there; the frame's start is bounded by the clock time
of the trigger (the shutter cannot open before it is asked to). The camera must save JPEG (set
its image quality to a JPEG mode): a raw file would need a raw decoder.

Controls (the widgets of libgphoto2's config tree; names differ between makers, the first one
present is used):

- ``exposure`` (s): ``shutterspeed`` / ``shutterspeed2`` choices ("1/60", "0.5", "30");
  set to the nearest choice.
- ``gain`` (x): ``iso`` choices relative to the lowest numeric ISO (the base).
- ``auto_exposure``: 0 when ``autoexposuremode`` / ``expprogram`` is manual ("Manual", "M");
  usually read-only (the mode dial): set it to M by hand.
- ``auto_white_balance``: 0 when ``whitebalance`` is not "Auto"; switching off picks
  "Daylight" (or the first fixed preset).
- ``autofocus``: 0 when ``focusmode`` is manual ("Manual", "MF"); often the lens's AF/MF switch.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from viewcomp.calib.hw.clock import MonotonicClock
from viewcomp.calib.hw.interface import Clock, ControlRange, DeviceError, Frame, FrameError
from viewcomp.calib.hw.optional import missing_package

WIDGETS: dict[str, tuple[str, ...]] = {
    "exposure": ("shutterspeed", "shutterspeed2"),
    "gain": ("iso",),
    "auto_exposure": ("autoexposuremode", "expprogram"),
    "auto_white_balance": ("whitebalance",),
    "autofocus": ("focusmode",),
}
MANUAL = ("manual", "m", "mf")


def parse_shutter(text: str) -> float | None:
    """A shutter-speed choice in seconds ("1/60" -> 1/60, "0.5", "30", '2"', "1/4000s");
    None for anything else ("bulb", "auto")."""
    t = text.strip().lower().rstrip('s"').strip()
    try:
        if "/" in t:
            num, den = t.split("/", 1)
            value = float(num) / float(den)
        else:
            value = float(t)
    except (ValueError, ZeroDivisionError):
        return None
    return value if math.isfinite(value) and value > 0 else None


def parse_iso(text: str) -> float | None:
    """An ISO choice as a number ("100" -> 100); None for "Auto" and the like."""
    try:
        value = float(text.strip())
    except ValueError:
        return None
    return value if value > 0 else None


def nearest(choices: list[str], parse: Any, want: float) -> str:
    """The choice whose parsed value is nearest ``want`` in log scale."""
    valued = [(c, parse(c)) for c in choices]
    valued = [(c, v) for c, v in valued if v is not None]
    if not valued:
        raise DeviceError(f"no numeric choice among {choices}")
    return min(valued, key=lambda cv: abs(math.log(cv[1] / want)))[0]


class GPhoto2Camera:
    """The gphoto2 camera ``spec`` (a model name or port such as ``usb:001,004``; empty: the
    first one found). See the module doc."""

    def __init__(self, spec: str = "", clock: Clock | None = None) -> None:
        try:
            import gphoto2 as gp
        except ImportError as e:
            raise missing_package("gphoto2", "gphoto2", e) from e
        self._gp = gp
        self._clock = clock if clock is not None else MonotonicClock()
        self._spec = spec
        self._cam = gp.Camera()
        try:
            if spec:
                self._select(spec)
            self._cam.init()
        except gp.GPhoto2Error as e:
            raise DeviceError(
                f"cannot open the gphoto2 camera {spec or '(first found)'} ({e}): connect it "
                "by USB, switch it on, close programs that hold it (gvfs, Shotwell), and check "
                "`gphoto2 --auto-detect`"
            ) from e
        self._model = spec or "camera"
        try:
            self._model = str(self._cam.get_summary()).splitlines()[0].split(":", 1)[-1].strip()
        except gp.GPhoto2Error:
            pass
        self._size: tuple[int, int] | None = None
        self._seq = 0

    def _select(self, spec: str) -> None:
        gp = self._gp
        ports = gp.PortInfoList()
        ports.load()
        abilities = gp.CameraAbilitiesList()
        abilities.load()
        found = list(abilities.detect(ports))
        for model, port in found:
            if spec in (model, port):
                self._cam.set_port_info(ports[ports.lookup_path(port)])
                self._cam.set_abilities(abilities[abilities.lookup_model(model)])
                return
        have = ", ".join(f"{m} ({p})" for m, p in found) or "none"
        raise DeviceError(f"no gphoto2 camera {spec!r}; connected: {have}")

    @property
    def name(self) -> str:
        """``gphoto2 MODEL``."""
        return f"gphoto2 {self._model}"

    @property
    def resolution(self) -> tuple[int, int]:
        """(width, height) of the JPEGs (takes one picture the first time it is asked)."""
        if self._size is None:
            self.grab()
        assert self._size is not None
        return self._size

    @property
    def channels(self) -> int:
        return 3

    def _widget(self, control: str) -> tuple[Any, Any]:
        gp = self._gp
        config = self._cam.get_config()
        for name in WIDGETS.get(control, ()):
            try:
                return config, config.get_child_by_name(name)
            except gp.GPhoto2Error:
                continue
        raise DeviceError(f"{self.name} has no {control} setting that gphoto2 can reach")

    @staticmethod
    def _choices(widget: Any) -> list[str]:
        return [str(widget.get_choice(i)) for i in range(widget.count_choices())]

    def controls(self) -> dict[str, ControlRange]:
        """The controls whose widgets this camera has (ranges from the choices)."""
        out: dict[str, ControlRange] = {}
        for control in WIDGETS:
            try:
                _, w = self._widget(control)
            except DeviceError:
                continue
            if control == "exposure":
                v = [s for s in map(parse_shutter, self._choices(w)) if s is not None]
                if v:
                    out[control] = ControlRange(min(v), max(v))
            elif control == "gain":
                v = [s for s in map(parse_iso, self._choices(w)) if s is not None]
                if v:
                    out[control] = ControlRange(1.0, max(v) / min(v))
            else:
                out[control] = ControlRange(0.0, 1.0, 1.0)
        return out

    def get(self, control: str) -> float:
        _, w = self._widget(control)
        value = str(w.get_value())
        if control == "exposure":
            s = parse_shutter(value)
            if s is None:
                raise DeviceError(f"{self.name}: shutter speed {value!r} is not a time")
            return s
        if control == "gain":
            iso = parse_iso(value)
            base = min(v for v in map(parse_iso, self._choices(w)) if v is not None)
            if iso is None:
                return math.nan  # automatic ISO
            return iso / base
        if control == "auto_white_balance":
            return 1.0 if value.lower() == "auto" else 0.0
        return 0.0 if value.lower() in MANUAL else 1.0

    def set(self, control: str, value: float) -> float:
        config, w = self._widget(control)
        choices = self._choices(w)
        if control == "exposure":
            choice = nearest(choices, parse_shutter, float(value))
        elif control == "gain":
            base = min(v for v in map(parse_iso, choices) if v is not None)
            choice = nearest(choices, parse_iso, base * float(value))
        elif control == "auto_white_balance":
            fixed = [c for c in choices if c.lower() != "auto"]
            if value:
                choice = next((c for c in choices if c.lower() == "auto"), "")
            else:
                choice = next(
                    (c for c in fixed if c.lower() == "daylight"), fixed[0] if fixed else ""
                )
        else:
            want = [c for c in choices if (c.lower() in MANUAL) == (value == 0)]
            choice = want[0] if want else ""
        if not choice:
            raise DeviceError(f"{self.name}: {control} has no setting for {value:g} ({choices})")
        try:
            w.set_value(choice)
            self._cam.set_config(config)
        except self._gp.GPhoto2Error as e:
            hint = {
                "auto_exposure": "turn the mode dial to M",
                "autofocus": "set the lens's AF/MF switch to MF",
            }.get(control, "set it on the camera")
            raise DeviceError(f"{self.name}: cannot set {control} ({e}): {hint}") from e
        return self.get(control)

    def grab(self) -> Frame:
        """One full capture, downloaded and deleted from the camera (module doc)."""
        import cv2

        gp = self._gp
        exposure = self.get("exposure")
        try:
            gain = self.get("gain")
        except DeviceError:
            gain = 1.0
        start = self._clock.now()
        try:
            path = self._cam.capture(gp.GP_CAPTURE_IMAGE)
            data = self._cam.file_get(path.folder, path.name, gp.GP_FILE_TYPE_NORMAL)
            raw = np.frombuffer(memoryview(data.get_data_and_size()), np.uint8)
        except gp.GPhoto2Error as e:
            raise FrameError(f"{self.name}: capture failed ({e})") from e
        try:
            self._cam.file_delete(path.folder, path.name)
        except gp.GPhoto2Error:
            pass  # some cameras keep the file: only the card fills up
        bgr = cv2.imdecode(raw, cv2.IMREAD_COLOR)
        if bgr is None:
            raise DeviceError(
                f"{self.name}: {path.name} is not a JPEG OpenCV can decode: set the camera's "
                "image quality to a JPEG mode (not RAW or RAW+JPEG)"
            )
        self._size = (int(bgr.shape[1]), int(bgr.shape[0]))
        self._seq += 1
        return Frame(
            image=np.ascontiguousarray(bgr[:, :, ::-1]),
            timestamp=start,
            exposure=exposure,
            gain=gain,
            sequence=self._seq,
        )

    def close(self) -> None:
        try:
            self._cam.exit()
        except self._gp.GPhoto2Error:
            pass
