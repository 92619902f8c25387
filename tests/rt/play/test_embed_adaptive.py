"""The embedding API (and so ``play``) with the adaptive tone map: each frame draws what the
numpy reference computes for the field that frame's parameters hold."""

from __future__ import annotations

import itertools
from typing import Any

import numpy as np
import pytest

from tests.support.calibrations import small_calibration
from viewcomp.calib.eval.testimages import natural_images
from viewcomp.calib.model.reference import compensate

GW, GH = 64, 32

pytestmark = pytest.mark.gl


def _read(fbo: Any) -> np.ndarray:
    data = np.frombuffer(fbo.read(components=3, alignment=1), np.uint8)
    return data.reshape(GH, GW, 3)[::-1]  # row 0 on top


@pytest.mark.parametrize("async_tone", [False, True], ids=["sync", "worker"])
def test_live_renderer_draws_the_reference_of_its_field(gl_ctx: Any, async_tone: bool) -> None:
    from viewcomp.rt.play.embed import LiveRenderer

    cal = small_calibration(GW, GH, screen="red")
    imgs = natural_images(GW, GH)
    # a cut after the third, to a dim shot: on this screen the search dims the bright coffee
    # to a quarter and leaves the half-bright astronaut at gain 1
    frames = [imgs["coffee"]] * 3 + [imgs["astronaut"] // 2] * 3
    fbo = gl_ctx.simple_framebuffer((GW, GH))
    fields = []
    try:
        with LiveRenderer(cal, gl_ctx, angle=60.0, eye_tau=0.0, tone="adaptive",
                          async_tone=async_tone, tone_hz=50.0) as live:  # fmt: skip
            for i, frame in enumerate(frames):
                record = live.render(frame, target=fbo, viewport=(0, 0, GW, GH), now=0.04 * i)
                p = record.params
                assert p.field is not None
                assert live.compensator.last_path.startswith("adaptive")
                want = compensate(p.model, frame, record.eye, p.alpha, p.beta, field=p.field)
                d = np.abs(_read(fbo).astype(int) - want.astype(int))
                assert d.max() <= 3 and np.mean(d > 1) <= 0.001, (i, d.max())
                fields.append(p.field)
    finally:
        fbo.release()
    if not async_tone:  # each frame's own field: eased within the shot, a new one at the cut
        moves = [float(np.abs(b.gain - a.gain).max()) for a, b in itertools.pairwise(fields)]
        assert max(moves[:2] + moves[3:]) < moves[2]
