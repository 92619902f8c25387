"""The people test's heads (tests/rt/track/test_tracker_people.py): photographs, hand-annotated
(pupil centres and nose tip read off enlarged crops with a pixel grid, never by YuNet or the
tracker), and a head scanned in 3-D with its authors' 3-D landmarks."""

from __future__ import annotations

import functools
from pathlib import Path

import cv2
import numpy as np
import pytest

from tests.support.scripts import load_script
from viewcomp.rt.track.simrelief import MeasuredRelief
from viewcomp.rt.track.simscan import Scan, read_obj
from viewcomp.rt.track.simscene import Person

# luispedro.jpg's pupil centres (the image's left eye first) and nose tip, pixels, marked by hand
LUISPEDRO_EYES = ((68.0, 170.0), (146.0, 157.0))
LUISPEDRO_TIP = (85.0, 212.0)


def luispedro_path() -> Path:
    """mahotas' demo photograph ``luispedro.jpg`` (a test dependency)."""
    try:
        import mahotas
    except ImportError:  # not skipped: the bias test must not vanish quietly
        pytest.fail('mahotas is missing: pip install -e ".[test]" (it ships luispedro.jpg)')
    return Path(mahotas.__file__).parent / "demos" / "data" / "luispedro.jpg"


@functools.cache
def people() -> list[Person]:
    """The three annotated photographs (pixels verified by eye on 4x crops with a 10-pixel
    grid): the astronaut, Grace Hopper, Luis Pedro Coelho (a head turned and tilted). The two
    photographed facing the camera are painted on the scanned head's measured relief
    (:func:`relief`); luispedro, photographed turned 34 degrees, on the model relief
    (:class:`~viewcomp.rt.track.simrelief.Ridge`): his far cheek, which his photograph saw at a
    slant, lies beyond the scan's narrower jaw, so drawn frontal on the scan's relief his face
    has holes where it finds no surface and YuNet reads it turned (median distance 1.06-1.12
    of the truth facing the camera or watching the screen)."""
    import matplotlib
    from skimage.data import astronaut

    mpl = Path(matplotlib.get_data_path()) / "sample_data" / "grace_hopper.jpg"
    lp = luispedro_path()
    face = relief()
    return [
        Person.annotated("astronaut", np.ascontiguousarray(astronaut()[:, :, ::-1]),
                         ((204, 101), (246, 104)), (222, 126), (224, 118, 88, 108), face),
        Person.annotated("hopper", cv2.imread(str(mpl)),
                         ((220, 189.5), (304, 186)), (265, 240), (262, 200, 105, 140), face),
        Person.annotated("luispedro", cv2.imread(str(lp)), LUISPEDRO_EYES, LUISPEDRO_TIP,
                         (135, 180, 110, 150)),
    ]  # fmt: skip


@functools.cache
def relief() -> MeasuredRelief:
    """The scanned head's face as a relief for the photographs (its texels of pyramid level 1,
    about 0.5 mm apart): a measured face, neither the tracker's model nor the simulator's
    ridge."""
    scan = scanned()
    return MeasuredRelief.of_surface(scan.texels(1)[0], scan.nose)


@functools.cache  # one load for every test: its texture levels are computed once
def scanned() -> Scan:
    """James Booth's head as menpo3d 0.8.6 ships it (``james.obj``: 6393 vertices in
    millimetres, a stereo texture ``james.jpg``; BSD, its LICENSE.txt beside it), fetched by
    ``scripts/fetch_scan.py``. Its 68 landmarks (``james.ljson``, iBUG's 68 points in 3-D,
    placed by the scan's authors): the eye centres are the means of the eye contours' six
    points, the mouth corners the mouth's first and seventh, the nose tip the nose's
    fourth (iBUG's 30)."""
    import json

    fetch = load_script("scripts/fetch_scan.py")
    bad = fetch.damaged()
    if bad:  # not skipped: the bias test must not vanish quietly
        pytest.fail(f"{', '.join(bad)} missing or damaged: python scripts/fetch_scan.py")
    where = fetch.DEST
    vertices, faces, uv = read_obj(where / "james.obj")
    texture = cv2.imread(str(where / "james.jpg"))
    doc = json.loads((where / "james.ljson").read_text(encoding="utf-8"))["groups"]["LJSON"]
    points = np.asarray(doc["landmarks"]["points"], np.float64)
    group = {g["label"]: points[g["mask"]] for g in doc["labels"]}
    eyes = np.stack([group["leye"].mean(axis=0), group["reye"].mean(axis=0)])
    mouth = group["mouth"][[0, 6]]
    return Scan.annotated("james", vertices, faces, uv, texture, eyes, mouth, group["nose"][3])
