"""Exports for other players: the mpv user shader.

- ``mpv``: `viewcomp export-mpv`: the compensation as an mpv user shader, for kiosks that run
  mpv.
"""
