"""Files of the calibration step: images, capture sets, patterns, checks, the bundle.

- ``bundle``: The calibration bundle: one versioned zip file, readable without pickle.
- ``calibration_bundle``: The bundle's layout: which arrays and meta.json entries hold each
  part of a calibration, written and read back.
- ``captureset``: The capture set: a folder of calibration captures (docs/INTERFACES.md).
- ``checks``: Checks of a capture set before any fit: saturation and darkness, with the fix
  named.
- ``imageio``: Reading and writing capture images, and atomic file writes.
- ``patterns``: Calibration patterns to project: Table 1 of the paper, a chessboard and Gray
  code.
"""
