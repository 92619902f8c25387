"""YuNet's reading of a crop averaged with its mirror image's (rt/track/yunet.py): the rows'
mirror is exact, and the averaged reading of a face is the mirror of its mirror image's,
where YuNet alone reads the two apart."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from skimage.data import astronaut

from viewcomp.rt.track.yunet import (
    YuNetConfig,
    YuNetDetector,
    mirror_average,
    mirror_match,
    mirrored,
)

ROW = np.array([10.0, 20.0, 30.0, 40.0, 15, 30, 33, 31, 24, 40, 18, 50, 31, 51, 0.9])


def test_mirrored_rows():
    """A row mirrored: its box's edges and every landmark at width - 1 - x, the eyes and the
    mouth corners swapped so the image's left one comes first; mirrored twice, itself."""
    m = mirrored(ROW, 100)[0]
    assert m[:4].tolist() == [100 - 1 - 40.0, 20.0, 30.0, 40.0]
    assert m[4:14].reshape(5, 2).tolist() == [
        [99 - 33, 31], [99 - 15, 30], [99 - 24, 40], [99 - 31, 51], [99 - 18, 50],
    ]  # fmt: skip
    assert m[14] == ROW[14]
    np.testing.assert_array_equal(mirrored(m, 100)[0], ROW)


def test_mirror_average_takes_the_nearest_face_or_none():
    """The mirrored image's reading nearest the row is averaged in (a face's own reading:
    the row unchanged); another face's, more than 0.3 box widths off, is not."""
    other = ROW.copy()
    other[0] += 50.0
    seen = mirrored(np.stack([other, ROW + 1.0]), 100)
    np.testing.assert_allclose(mirror_match(ROW, seen, 100), ROW + 1.0)
    np.testing.assert_allclose(mirror_average(ROW, mirror_match(ROW, seen, 100)), ROW + 0.5)
    assert mirror_match(ROW, seen[:1], 100) is None
    assert mirror_match(ROW, seen[:0], 100) is None
    np.testing.assert_array_equal(mirror_average(ROW, None), ROW)


def _centred_face() -> tuple[np.ndarray, np.ndarray]:
    """A frame with the astronaut's face, eyes about 25 pixels apart, at its middle column,
    and a box about the face whose mirror image is itself."""
    photo = cv2.resize(astronaut()[:, :, ::-1], None, fx=0.6, fy=0.6, interpolation=cv2.INTER_AREA)
    # the face's centre in the photograph, marked by hand (eyes at (204, 101) and (246, 104))
    cx, cy = 0.6 * 225.0, 0.6 * 110.0
    frame = np.full((360, 640, 3), 90, np.uint8)
    x0, y0 = int(320 - cx), int(180 - cy)
    frame[y0 : y0 + photo.shape[0], x0 : x0 + photo.shape[1]] = photo[: 360 - y0, : 640 - x0]
    w = 40.0
    return frame, np.array([320.0 - w / 2, 180.0 - w / 2, w, w])


@pytest.mark.parametrize("mirror", [True, False])
def test_a_face_and_its_mirror_image_are_read_alike(mirror):
    """The face refined in a crop that is its own mirror image, and in the mirrored frame:
    averaged with the mirror's reading, the two readings are each other's mirror to a
    hundredth of a pixel (the same two detections, taken in the other order); YuNet alone
    reads them apart, which this test sees (more than 0.2 pixels somewhere)."""
    frame, box = _centred_face()
    det = YuNetDetector(YuNetConfig(mirror=mirror))
    a = det.refine(frame, box)
    b = det.refine(np.ascontiguousarray(frame[:, ::-1]), box)
    assert a is not None and b is not None
    apart = np.abs(a[4:14] - mirrored(b, frame.shape[1])[0, 4:14]).max()
    if mirror:
        assert apart < 0.01, apart
    else:
        assert apart > 0.2, apart
