"""The people test's photographs (tests/rt/track/test_tracker_people.py), hand-annotated:
pupil centres and nose tip read off enlarged crops with a pixel grid, never by YuNet or the
tracker."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from viewcomp.rt.track.simscene import Person


def people() -> list[Person]:
    """The three annotated photographs (pixels verified by eye on 4x crops with a 10-pixel
    grid): the astronaut, Grace Hopper, Luis Pedro Coelho (a head turned and tilted)."""
    import matplotlib
    from skimage.data import astronaut

    try:
        import mahotas
    except ImportError:  # not skipped: the bias test must not vanish quietly
        pytest.fail('mahotas is missing: pip install -e ".[test]" (it ships luispedro.jpg)')
    mpl = Path(matplotlib.get_data_path()) / "sample_data" / "grace_hopper.jpg"
    lp = Path(mahotas.__file__).parent / "demos" / "data" / "luispedro.jpg"
    return [
        Person.annotated("astronaut", np.ascontiguousarray(astronaut()[:, :, ::-1]),
                         ((204, 101), (246, 104)), (222, 126), (224, 118, 88, 108)),
        Person.annotated("hopper", cv2.imread(str(mpl)),
                         ((220, 189.5), (304, 186)), (265, 240), (262, 200, 105, 140)),
        Person.annotated("luispedro", cv2.imread(str(lp)),
                         ((68, 170), (146, 157)), (85, 212), (135, 180, 110, 150)),
    ]  # fmt: skip
