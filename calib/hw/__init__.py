"""Calibration with hardware: the capture procedure and the device interfaces (no GL).

- ``devices``: The projector and the camera of `viewcomp capture`, behind one small interface.
- ``procedure``: The capture procedure of `viewcomp capture`: patterns in, a checked capture set
  out.
"""
