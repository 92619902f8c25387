"""Calibration with hardware: the capture procedure and the device interfaces (no GL).

- ``interface``: the device protocols (camera, projector, clock) every backend implements.
- ``devices``: the backends of `viewcomp capture` (OpenCV camera, the simulated rig).
- ``procedure``: the capture procedure of `viewcomp capture`: patterns in, a checked capture set
  out.
- ``livechecks``: the checks run on each capture as it arrives.
- ``bracket``: HDR brackets through the camera's exposure control.
- ``plan``: every pattern of a camera-space capture, in order.
"""
