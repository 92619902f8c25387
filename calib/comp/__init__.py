"""The per-frame CPU side of compensation: the tone map and each frame's parameters.

- ``compensation``: The CPU side of compensating frames: what the per-pixel formula needs for
  each frame.
- ``tonemap``: The tone map C_c = alpha C_w + beta (Eqs. 21, 22) and how it is chosen.
"""
