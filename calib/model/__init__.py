"""The runtime model (calibration -> run time contract) and its numpy reference.

- ``runtime``: ``RuntimeModel``, what the per-frame formula needs for one method, as float32
  arrays: the contract between the fits and every backend.
- ``shader_inputs``: What the shaders read, prepared on the CPU (numpy only): the per-pixel
  maps' texels, the inverse LUT's position, the paper method's folded matrices.
- ``reference``: The numpy reference of the per-frame compensation (docs/RUNTIME.md): the
  ground truth the GLSL shader and the mpv export are tested against.
"""
