"""The physical simulator of projector, screen and camera; simulated capture sets.

- ``materials``: Measured BRDFs (neural form) evaluated in numpy, and a finite projector lens.
- ``simcamera``: The simulated calibration camera in its own image: what `simulate --space
  camera` writes.
- ``simulate``: Simulated capture sets: what `viewcomp simulate` writes (projector or camera
  space).
- ``simulator``: A physical simulator of projector, screen and camera (docs/MODEL.md section 5).
"""
