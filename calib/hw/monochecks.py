"""The live checks for a mono camera (:mod:`viewcomp.calib.hw.mono` says why they differ)."""

from __future__ import annotations

import numpy as np

from viewcomp.calib.hw.livechecks import LiveChecks
from viewcomp.calib.io.imageio import CaptureError


class MonoChecks(LiveChecks):
    """:class:`LiveChecks` for a mono camera: a colour pattern must light the screen more than
    gray does (its one channel rises), since which channel rises most cannot be seen."""

    def _colour(self, sub: str, rel: str, name: str, lin: np.ndarray) -> None:
        d = float((lin - self.gray[sub])[self.lit[sub]].mean())
        if not d > 0:
            raise CaptureError(
                f"{rel}: the {name} pattern does not light the screen more than gray does "
                f"(change {d:+.4f}): check that the window is on the projector"
            )
