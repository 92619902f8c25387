"""The radiometric fits: the paper's method and the per-pixel method, and calibrate().

- ``calibrate``: From a capture set to a calibration bundle, and back: both methods in one file.
- ``colourguide``: Edge-aware smoothing of the per-pixel colour mixing, guided by the screen's
  own colour.
- ``paper``: The paper's method (docs/MODEL.md section 2, steps 1-7), with the errata of section 3
  applied.
- ``pixel``: The per-pixel method (docs/MODEL.md section 4).
"""
