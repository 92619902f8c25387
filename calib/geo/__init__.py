"""Geometric calibration: camera frames of a capture set onto the projector's grid.

- ``geocal``: Geometric calibration of a camera-space capture set: from camera frames to the
  projector grid.
"""
