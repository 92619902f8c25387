"""Mono cameras (``Camera.channels == 1``): what their captures can and cannot calibrate.

A mono camera measures one band of light. Its frames are stored as three equal channels
(R = G = B, the same 0..1 scale as a colour capture), so the capture set's format is unchanged.
What such a set holds: the geometry (chessboard, Gray code, the camera-moved checks) and, per
pixel, one grey level of brightness response, albedo, vignetting and ambient light. What it
cannot hold is colour: how much each projector primary adds to each camera channel (the colour
mixing), the screen's colour, any colour correction. Capture therefore checks only that each
colour pattern lights the screen (:class:`~viewcomp.calib.hw.monochecks.MonoChecks`) and, before
writing, the geometry only; `viewcomp calibrate`, whose fits need the colour mixing, refuses a
set whose colour captures are grey in every channel
(:func:`~viewcomp.calib.io.checks.is_mono_set`) rather than fitting a mixing matrix from
nothing.
"""

from __future__ import annotations

MONO_LIMITS = (
    "its captures hold the geometry and one grey level per pixel, not colour (no colour "
    "mixing, no screen colour): they are stored as three equal channels, and `viewcomp "
    "calibrate` refuses the set because its fits need the colour mixing; use a colour camera "
    "to calibrate compensation"
)
