"""Errors of the calibration step that name the capture at fault and what to do."""

from __future__ import annotations


class FitError(ValueError):
    """A fit that cannot succeed from these captures.

    ``capture`` names the capture at fault (e.g. ``"screen/ramp"``), ``reason`` says why and
    what to change.
    """

    def __init__(self, capture: str, reason: str) -> None:
        super().__init__(f"{capture}: {reason}")
        self.capture = capture
        self.reason = reason
