"""Geometric calibration: camera frames of a capture set onto the projector's grid.

- ``captures``: The captures of a camera-space set, loaded on demand as linear float32.
- ``chessboard``: The projected chessboard's corners in a camera image, and Zhang's method.
- ``graycode``: Decoding the Gray-code planes into projector column and row per camera pixel.
- ``camresponse``: The camera's response, estimated from light's additivity in Gray-code pairs.
- ``projmap``: The projector -> camera map (homography, lens, cubic), and rectification.
- ``checks``: The camera did not move, the patterns are in order, the Gray code covers all.
- ``rectify``: The whole step: ``calibrate_geometry`` and ``rectify_capture_set``.
"""
