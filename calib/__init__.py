"""viewcomp's calibration side: numpy, SciPy and OpenCV, never OpenGL, never viewcomp.rt.

Sub-packages, in the order data flows through them: ``world`` (rig.toml, eyes, geometry,
camera responses), ``io`` (capture sets, patterns, the bundle), ``geo`` (camera frames onto
the projector grid), ``fit`` (the paper's method and the per-pixel method), ``model`` (the
runtime model and its numpy reference), ``comp`` (each frame's tone map and parameters);
beside them ``sim`` (the simulator), ``eval`` (the paper's Section 5) and ``hw`` (capture with
a real projector and camera).
"""
