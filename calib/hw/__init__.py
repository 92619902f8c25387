"""Calibration with hardware: the capture procedure and the device interfaces (no GL).

- ``interface``: the device protocols (camera, projector, clock) every backend implements.
- ``opencv_camera``, ``simrig``: the OpenCV camera and the simulated rig (backends).
- ``clock``, ``frames``, ``reader``, ``latency``, ``camlock``: clocks, frame averaging,
  presentation sync with retries, the latency sentinel, locking the camera.
- ``procedure``: the capture procedure of `viewcomp capture`: patterns in, a checked capture set
  out.
- ``livechecks``: the checks run on each capture as it arrives.
- ``bracket``: HDR brackets through the camera's exposure control.
- ``plan``: every pattern of a camera-space capture, in order.
"""
