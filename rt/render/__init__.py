"""Headless rendering of images and videos (viewcomp render), and eye tracks.

- ``pipeline``: Headless rendering of an image or a video through the compensation (``viewcomp
  render``).
- ``tracks``: Eye tracks: where the viewer is at time t, as a callable ``t_seconds -> eye
  (3,)``.
"""
