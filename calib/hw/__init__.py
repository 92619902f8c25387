"""Calibration with hardware: the capture procedure and the device interfaces (no GL).

- ``interface``: the device protocols (camera, projector, clock) every backend implements.
- ``clock``: the real clock and the simulated one.
- ``backends``: camera backends by name and the ``module:factory`` plug-in point;
  ``opencv_camera``, ``gphoto2_camera``, ``genicam_camera`` the built-in ones (the last two
  import their optional packages only when used: ``optional``); ``simrig`` the simulated
  projector and camera.
- ``procedure``: the capture procedure of `viewcomp capture`: patterns in, a checked capture set
  out; ``session`` its set-up and one fresh capture.
- ``camlock``: locking the camera's automatic modes; ``latency``: the projector -> camera
  latency sentinel; ``autoexposure``: the exposure search; ``reader``: fresh frames
  (presentation sync) with retries; ``frames``: averaging frames into a capture, and how
  many by default;
  ``progress``: progress with the time left.
- ``bracket``: HDR brackets in whole projector refresh periods; ``hdrresponse``: the camera's
  response from a bracket.
- ``mono``, ``monochecks``: what a mono camera can calibrate, and its live checks.
- ``livechecks``: the checks run on each capture as it arrives.
- ``plan``: every pattern of a camera-space capture, in order.
"""
