"""A machine-vision camera through GenICam / GenTL with the ``harvesters`` package (optional:
imported when this backend is used; it needs the camera maker's GenTL producer, a ``.cti``
file, which ``--camera PRODUCER.cti[#SERIAL]`` names).

The camera runs in software-trigger mode: :meth:`GenICamCamera.grab` fires
``TriggerSoftware`` and fetches that frame, so its exposure started after the trigger's clock
time (the frame's timestamp). Frames are raw sensor values (``linear``: the camera's
``GammaEnable`` is switched off where present): Mono8/10/12/16 or RGB8/BGR8 (set a Bayer
camera to its own RGB8 debayering; raw Bayer is refused rather than guessed).

Controls are SFNC nodes: ``exposure`` = ``ExposureTime`` (us), ``gain`` = ``Gain`` (dB,
converted to a linear factor over its minimum), ``auto_exposure`` = ``ExposureAuto``,
``auto_white_balance`` = ``BalanceWhiteAuto`` ("Off" / "Continuous").
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from viewcomp.calib.hw.clock import MonotonicClock
from viewcomp.calib.hw.interface import Clock, ControlRange, DeviceError, Frame, FrameError
from viewcomp.calib.hw.optional import missing_package

FORMATS = {"Mono8": 8, "Mono10": 10, "Mono12": 12, "Mono16": 16, "RGB8": 8, "BGR8": 8}
AUTO_NODES = {"auto_exposure": "ExposureAuto", "auto_white_balance": "BalanceWhiteAuto"}


class GenICamCamera:
    """The GenICam camera of ``spec`` = ``PRODUCER.cti[#SERIAL]`` (see the module doc)."""

    def __init__(self, spec: str, clock: Clock | None = None) -> None:
        try:
            from harvesters.core import Harvester
        except ImportError as e:
            raise missing_package("harvesters", "genicam", e) from e
        self._clock = clock if clock is not None else MonotonicClock()
        cti, _, serial = spec.partition("#")
        if not cti.endswith(".cti"):
            raise DeviceError(
                f"--camera {spec!r}: the genicam backend takes PRODUCER.cti[#SERIAL], the "
                "camera maker's GenTL producer file (e.g. from its SDK) and a serial number"
            )
        if not Path(cti).is_file():
            raise DeviceError(
                f"--camera {spec!r}: no GenTL producer file {cti}: give the path of the camera "
                "maker's .cti (its SDK installs one, e.g. under /opt/<vendor>/lib)"
            )
        self._h = Harvester()
        try:
            self._h.add_file(cti, check_existence=True)
            self._h.update()
            if not self._h.device_info_list:
                raise DeviceError(f"the GenTL producer {cti} finds no camera: connect one")
            self._ia = self._h.create({"serial_number": serial} if serial else 0)
        except DeviceError:
            self._h.reset()
            raise
        except Exception as e:  # harvesters raises its own and GenTL's exception types
            self._h.reset()
            raise DeviceError(f"cannot open a GenICam camera through {cti} ({e})") from e
        self._nm = self._ia.remote_device.node_map
        fmt = str(self._node("PixelFormat").value)
        if fmt not in FORMATS:
            self._close()
            raise DeviceError(
                f"GenICam camera {serial or 0}: pixel format {fmt} is not read; set PixelFormat "
                f"to one of {', '.join(FORMATS)}"
            )
        self._bits = FORMATS[fmt]
        self._fmt = fmt
        try:
            self._node("TriggerMode").value = "On"
            self._node("TriggerSource").value = "Software"
        except Exception as e:
            self._close()
            raise DeviceError(
                f"GenICam camera {serial or 0} has no software trigger ({e}): write a plug-in "
                "(--camera-backend module:factory) for its own SDK"
            ) from e
        if hasattr(self._nm, "GammaEnable"):
            self._nm.GammaEnable.value = False
        self._serial = serial or str(self._ia.remote_device.node_map.DeviceSerialNumber.value)
        self._size = (int(self._node("Width").value), int(self._node("Height").value))
        self._ia.start()
        self._seq = 0

    def _node(self, name: str) -> Any:
        node = getattr(self._nm, name, None)
        if node is None:
            raise DeviceError(f"{self.name} has no GenICam node {name}")
        return node

    @property
    def name(self) -> str:
        return f"GenICam camera {getattr(self, '_serial', '?')}"

    @property
    def resolution(self) -> tuple[int, int]:
        return self._size

    @property
    def channels(self) -> int:
        return 1 if self._fmt.startswith("Mono") else 3

    def controls(self) -> dict[str, ControlRange]:
        out: dict[str, ControlRange] = {}
        if hasattr(self._nm, "ExposureTime"):
            n = self._nm.ExposureTime
            out["exposure"] = ControlRange(n.min * 1e-6, n.max * 1e-6)
        if hasattr(self._nm, "Gain"):
            n = self._nm.Gain
            out["gain"] = ControlRange(1.0, 10 ** ((n.max - n.min) / 20))
        for control, node in AUTO_NODES.items():
            if hasattr(self._nm, node):
                out[control] = ControlRange(0.0, 1.0, 1.0)
        return out

    def get(self, control: str) -> float:
        if control == "exposure":
            return float(self._node("ExposureTime").value) * 1e-6
        if control == "gain":
            n = self._node("Gain")
            return 10 ** ((float(n.value) - float(n.min)) / 20)
        if control in AUTO_NODES:
            return 0.0 if str(self._node(AUTO_NODES[control]).value) == "Off" else 1.0
        raise DeviceError(f"{self.name} has no control {control!r}")

    def set(self, control: str, value: float) -> float:
        try:
            if control == "exposure":
                n = self._node("ExposureTime")
                n.value = min(max(float(value) * 1e6, n.min), n.max)
            elif control == "gain":
                n = self._node("Gain")
                n.value = min(max(float(n.min) + 20 * math.log10(max(value, 1e-9)), n.min), n.max)
            elif control in AUTO_NODES:
                self._node(AUTO_NODES[control]).value = "Off" if value == 0 else "Continuous"
            else:
                raise DeviceError(f"{self.name} has no control {control!r}")
        except DeviceError:
            raise
        except Exception as e:
            raise DeviceError(f"{self.name}: cannot set {control} = {value:g} ({e})") from e
        return self.get(control)

    def grab(self) -> Frame:
        exposure, gain = (
            self.get("exposure"),
            self.get("gain") if "gain" in self.controls() else 1.0,
        )
        start = self._clock.now()
        try:
            self._node("TriggerSoftware").execute()
            with self._ia.fetch(timeout=exposure + 5.0) as buffer:
                c = buffer.payload.components[0]
                shape = (c.height, c.width) if self.channels == 1 else (c.height, c.width, 3)
                image = np.array(c.data, copy=True).reshape(shape)
        except Exception as e:  # a timeout or an incomplete buffer: one failed read
            raise FrameError(f"{self.name}: no frame ({e})") from e
        if self._fmt == "BGR8":
            image = np.ascontiguousarray(image[:, :, ::-1])
        image = image.astype(np.uint8 if self._bits == 8 else np.uint16, copy=False)
        self._seq += 1
        return Frame(image, start, exposure, gain, self._seq, bits=self._bits, linear=True)

    def _close(self) -> None:
        try:
            self._ia.destroy()
        finally:
            self._h.reset()

    def close(self) -> None:
        try:
            self._ia.stop()
        finally:
            self._close()
