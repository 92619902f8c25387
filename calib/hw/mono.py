"""Mono cameras (``Camera.channels == 1``): what their captures hold and how they calibrate.

A mono camera measures one band of light. Its frames are stored as three equal channels
(R = G = B, the same 0..1 scale as a colour capture), so the capture set's format is unchanged.
It cannot see colour, so its stages add each projector primary shown alone, at the gray level
and on the ramp (:func:`~viewcomp.calib.io.patterns.primary_patterns`, in the plan of
:func:`~viewcomp.calib.hw.plan.capture_plan`); `viewcomp calibrate` then fits both methods in
the per-primary basis (:mod:`viewcomp.calib.fit.mono`, docs/MODEL.md "Mono cameras"). Capture
checks only that each colour pattern lights the screen
(:class:`~viewcomp.calib.hw.monochecks.MonoChecks`) and, before writing, the geometry only
(colour order cannot be checked in grey captures).
"""

from __future__ import annotations

MONO_LIMITS = (
    "its captures hold one grey level per pixel, not colour: each projector primary is also "
    "captured alone, and `viewcomp calibrate` fits the screen per primary (the surface's colour "
    'seen only through the three primaries\' gains; docs/MODEL.md, "Mono cameras")'
)
