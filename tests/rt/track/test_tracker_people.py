"""viewcomp track on real people's heads placed by their *eyes*, not by a detector.

Three photographs that installed packages ship, each annotated once by hand (pupil centres and
nose tip read off enlarged crops with a pixel grid, never by YuNet or the tracker), and a head
scanned in 3-D:

- ``astronaut``: Eileen Collins, NASA (public domain), scikit-image's ``data.astronaut()``;
- ``hopper``: Grace Hopper with glasses, US Navy (public domain), matplotlib's sample data
  ``grace_hopper.jpg``;
- ``luispedro``: Luis Pedro Coelho, mahotas' demo data ``luispedro.jpg`` (mahotas, MIT), a
  head turned (33.6 degrees: where the simulated head's relief puts the hand-marked nose
  on the face's midline) and tilted in the photograph; the head is turned back by that
  much, so "frontal" faces the camera for him too, and turned the other way it is drawn
  from the mirrored photograph (``posed``: turned across frontal, the photographed nose
  stayed on its side and YuNet read him nearly frontal).

The astronaut and Hopper, photographed facing the camera, are painted on the scanned head's
measured face (``tests.support.people.relief``: its nose, eye sockets, cheeks and lips where a
real face has them); luispedro, photographed turned, on the model relief (a cylinder and a
nose ridge: his far cheek lies beyond the scan's jaw). A head drawn far from its photograph's
turn keeps the nose's look as photographed (:mod:`viewcomp.rt.track.simscene`): drawn turned
25 and 45 degrees, YuNet's nose moves a median 0.70 and 0.73 (the astronaut; 0.55 and 0.46 on
the model relief), 0.69 and 0.66 (Hopper; 0.64 and 0.48) and 0.73 and 0.77 (luispedro) times
as far from the eyes' midpoint as the drawn tip (on real photographs, along its own eye
line, it stands 0.59-1.00 as far out as a hand-marked tip).
- ``james``: James Booth, menpo3d's textured face scan (menpo3d 0.8.6's data, BSD; fetched
  by ``scripts/fetch_scan.py``) with its authors' 68 landmarks in 3-D
  (:mod:`viewcomp.rt.track.simscan`): measured surface, so a turned head shows its own nose
  and cheek; the only head here whose turned views are not redrawn from one photograph
  (YuNet's nose moves a median 0.82 and 0.87 as far as his tip, turned 25 and 45 degrees).

The photographs are drawn as 2.5-D heads (:mod:`viewcomp.rt.track.simscene`), each with a 63 mm
interpupillary distance at a known 3-D eye midpoint in a simulated 1280x720 webcam (90 degrees
wide, the screen's top edge), facing the camera or turned by a known yaw (25 or 45 degrees
either way), or facing a point of the picture below the camera ("watching": what a viewer
does, the head nodding against the camera by up to 30 degrees), so the ranging
(:mod:`viewcomp.rt.track.anatomy`) is judged against an anatomical truth. Frames come from an
ideal camera with a little noise, or ("webcam") through the calibration's emulated webcam
(:func:`viewcomp.rt.track.simscene.through_webcam`). Run this file as a script for the table
per person and condition.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.support.people import people, scanned
from viewcomp.rt.track.anatomy import head_pose
from viewcomp.rt.track.run import Pipeline, TrackOptions
from viewcomp.rt.track.simscan import Scan
from viewcomp.rt.track.simscene import Person, finish, render_person, through_webcam
from viewcomp.rt.track.simwalk import background, walk_camera
from viewcomp.rt.track.source import ArraySource
from viewcomp.rt.track.tracker import EyeTracker, TrackerConfig
from viewcomp.rt.track.yunet import YuNetDetector

CONDITIONS = {
    "frontal": {},
    "turned 25": {"turn": math.radians(25)},
    "turned 45": {"turn": math.radians(45)},
    "dim": {"gain": 0.3, "noise": 0.02},
    "occluded": {"occluder": (-0.9, 0.75, 0.9, 2.0)},  # a hand over mouth and chin
    # facing a point of the picture (x within 0.5 m of the screen's centre, y within 0.3 m),
    # not the camera above it: the head nods against the camera by up to 30 degrees
    "watching": {"watch": (0.5, 0.3)},
    # facing the camera, seen through the calibration's emulated webcam (calib.emu: optics,
    # a Bayer sensor's noise, denoising, sharpening, MJPEG at 80) instead of an ideal camera
    "webcam": {"webcam": True},
}


def heads() -> list[Person | Scan]:
    """The three photographs, then the scanned head (its eye centres 63 mm apart too)."""
    return [*people(), scanned()]


def look_at(kw: dict, rng: np.random.Generator) -> np.ndarray | None:
    """Where a condition's head faces: a random point of the screen (z = 0) for
    ``"watch"``, else None (the camera)."""
    if "watch" not in kw:
        return None
    hx, hy = kw["watch"]
    return np.array([rng.uniform(-hx, hx), rng.uniform(-hy, hy), 0.0])


def poses(n: int, seed: int) -> np.ndarray:
    """(n, 3) eye midpoints, metres: 0.8..3.5 m from the screen centre at 30..150 degrees,
    heights 0..0.3 m, kept where the simulated webcam sees the head whole."""
    dev = walk_camera()
    rng = np.random.default_rng(seed)
    out: list[np.ndarray] = []
    while len(out) < n:
        d, th = rng.uniform(0.8, 3.5), math.radians(rng.uniform(30, 150))
        e = np.array([d * math.cos(th), rng.uniform(0.0, 0.3), d * math.sin(th)])
        uv = dev.project(e[None])[0]
        if np.all(np.isfinite(uv)) and 80 < uv[0] < 1200 and 80 < uv[1] < 640:
            out.append(e)
    return np.asarray(out)


def measure(n: int = 12, seed: int = 0) -> dict[tuple[str, str], dict[str, np.ndarray]]:
    """Per (person, condition): the true eyes (n, 3), the measured eyes (n, 3) (NaN where no
    face was found) from one frame each: YuNet, :func:`head_pose` and the eye a fresh
    :class:`EyeTracker` gives the face (a viewer not known yet; no filter)."""
    dev = walk_camera()
    back = background(dev.resolution, seed)
    det = YuNetDetector(device=dev)  # as the pipeline makes it: views pointed at the faces
    out = {}
    for k, person in enumerate(heads()):
        for j, (cond, kw) in enumerate(CONDITIONS.items()):
            truth = poses(n, seed + 100 * k + j)
            rng = np.random.default_rng((seed, k, j))
            got = np.full_like(truth, np.nan)
            for i, e in enumerate(truth):
                # the head's yaw toward the camera, either way; a photograph turned by
                # itself (luispedro) is turned back by its own yaw first, or mirrored
                who, turn = person.posed((1.0 if i % 2 else -1.0) * kw.get("turn", 0.0))
                f = who.render(back, dev, e, turn, gain=kw.get("gain", 1.0),
                               occluder=kw.get("occluder"), look=look_at(kw, rng))  # fmt: skip
                if kw.get("webcam"):
                    frame = through_webcam(f, rng)
                else:
                    frame = finish(f, rng, kw.get("noise", 0.01))
                faces = det.detect(frame)
                if len(faces):  # the eye a face that starts a track is given
                    pose = head_pose(dev, faces.landmarks[:1])
                    got[i] = EyeTracker().update(pose.eyes, faces.boxes[:1], 0.0, pose)[0]
            out[person.name, cond] = {"truth": truth, "got": got}
    return out


def measure_tracked(cond: str, n: int = 12, seed: int = 0) -> dict[str, dict[str, np.ndarray]]:
    """Per person, the poses of :func:`measure` for ``cond`` seen by ``viewcomp track``'s
    pipeline (YuNet, file mode) as a viewer it already tracks: each pose is the second frame
    (0.1 s later) after the same pose with nothing over the face, with the condition's
    turn and light in both (a hand raised over the mouth of a viewer already seen). The eye
    of the second frame as the tracker ranged it (``Track.raw``, before the filter; NaN where
    not seen), as :func:`measure` gives them."""
    dev = walk_camera()
    back = background(dev.resolution, seed)
    j = list(CONDITIONS).index(cond)
    kw = CONDITIONS[cond]
    out = {}
    for k, person in enumerate(heads()):
        truth = poses(n, seed + 100 * k + j)
        rng = np.random.default_rng((seed, k, j, 1))
        got = np.full_like(truth, np.nan)
        for i, e in enumerate(truth):
            who, turn = person.posed((1.0 if i % 2 else -1.0) * kw.get("turn", 0.0))
            look = look_at(kw, rng)
            frames = [
                finish(who.render(back, dev, e, turn, gain=kw.get("gain", 1.0),
                                  occluder=occ, look=look), rng, kw.get("noise", 0.01))
                for occ in (None, kw.get("occluder"))
            ]  # fmt: skip
            pipeline = Pipeline(ArraySource(frames, 10.0), dev, TrackOptions())
            for fr in pipeline.source:
                pipeline.step(fr)
            seen = [tr for tr in pipeline.tracker.tracks if tr.seen == fr.t]
            pipeline.close()
            if seen:
                got[i] = seen[0].raw
        out[person.name] = {"truth": truth, "got": got}
    return out


def measure_turning(
    turn_deg: float, n: int = 12, seed: int = 0, step: float = 0.8, face_height: bool = True
) -> dict[str, dict[str, np.ndarray]]:
    """Per person, a viewer who watches the screen and turns their head while walking, seen
    by ``viewcomp track``'s pipeline (YuNet, file mode, 10 frames/s): four frames facing a
    point on the screen (x within 0.4 m of its centre, y within 0.25 m: the head nods
    against the camera above it), then three turned by ``turn_deg`` (either way), walking
    from up to ``step`` metres away toward the pose of :func:`measure` (``"turned 45"``'s
    poses), reached in the last frame. The eyes of the turned frames as the tracker ranged
    them (``Track.raw``, before the filter; NaN where not seen): ``truth`` and ``got``
    (3 n, 3). ``face_height``: the tracker's (:class:`TrackerConfig`)."""
    dev = walk_camera()
    back = background(dev.resolution, seed)
    j = list(CONDITIONS).index("turned 45")
    out = {}
    for k, person in enumerate(heads()):
        ends = poses(n, seed + 100 * k + j)
        starts = poses(4 * n, seed + 100 * k + j + 50)
        rng = np.random.default_rng((seed, k, j, 2))
        truth, got = [], []
        for i, b in enumerate(ends):
            near = starts[np.linalg.norm(starts - b, axis=1) <= step]
            a = near[0] if len(near) else b
            look = np.array([rng.uniform(-0.4, 0.4), rng.uniform(-0.25, 0.25), 0.0])
            sign = 1.0 if i % 2 else -1.0
            path = [a + (b - a) * f / 6.0 for f in range(7)]
            turns = [0.0] * 4 + [sign * math.radians(turn_deg)] * 3
            frames = []
            for e, yaw in zip(path, turns, strict=True):
                who, turn = person.posed(yaw)
                frames.append(finish(who.render(back, dev, e, turn, look=look), rng))
            opts = TrackOptions(tracker=TrackerConfig(face_height=face_height))
            pipeline = Pipeline(ArraySource(frames, 10.0), dev, opts)
            for f, fr in enumerate(pipeline.source):
                pipeline.step(fr)
                if f >= 4:
                    seen = [tr for tr in pipeline.tracker.tracks if tr.seen == fr.t]
                    truth.append(path[f])
                    got.append(seen[0].raw if seen else np.full(3, np.nan))
            pipeline.close()
        out[person.name] = {"truth": np.asarray(truth), "got": np.asarray(got)}
    return out


def scores(truth: np.ndarray, got: np.ndarray) -> dict[str, float]:
    """Found share; within 10 cm in x and y and 10 % in distance (share of all frames);
    the median distance ratio (measured / true, from the camera)."""
    dev = walk_camera()
    p = np.asarray(dev.position)
    found = np.all(np.isfinite(got), axis=1)
    ratio = np.linalg.norm(got - p, axis=1) / np.linalg.norm(truth - p, axis=1)
    ok = found.copy()
    dx = np.abs(got[found, 0] - truth[found, 0])
    dy = np.abs(got[found, 1] - truth[found, 1])
    ok[found] = (dx < 0.1) & (dy < 0.1) & (np.abs(ratio[found] - 1) < 0.1)
    median = float(np.median(ratio[found])) if found.any() else math.nan
    return {"found": float(found.mean()), "within": float(ok.mean()), "median_ratio": median}


def pooled(
    measured: dict[tuple[str, str], dict[str, np.ndarray]],
    name: str,
    conds: tuple[str, ...] | dict = CONDITIONS,
) -> dict[str, float]:
    """:func:`scores` of one person's frames in the conditions ``conds``, taken together."""
    t = np.concatenate([measured[name, c]["truth"] for c in conds])
    g = np.concatenate([measured[name, c]["got"] for c in conds])
    return scores(t, g)


@pytest.fixture(scope="module")
def measured():
    return measure()


NAMES = ("astronaut", "hopper", "luispedro", "james")
# Where the tracker falls short of the median criterion, measured (12 frames a cell,
# seed 0): expected failures, strict (a pass means the reason is out of date):
PAINTED = (
    "%s: her photograph, taken frontal, redrawn turned keeps its painted nose, which YuNet "
    "reads moving %s as far as the drawn tip (0.59-1.00 on real photographs; the ranging "
    "allows 0.8-1.25 of its model's, anatomy.NOSE_LAG): the turn is read short, the distance "
    "long"
)
SHORT = {
    ("hopper", "turned 45"): PAINTED % ("1.120", "0.66"),
    ("james", "frontal"): "0.946: YuNet puts his eyes about 5 % farther apart than the "
    "scan's eye centres, which his pupils marked by hand on its texture match across within "
    "a millimetre (0.948 median from the eyes alone), 92 % within",
}


def _cell(name: str, cond: str) -> object:
    """One (person, condition) case, marked where it is a known shortfall."""
    if (name, cond) in SHORT:
        return pytest.param(
            name, cond, marks=pytest.mark.xfail(strict=True, reason=SHORT[name, cond])
        )
    return pytest.param(name, cond)


@pytest.mark.slow
@pytest.mark.parametrize(("name", "cond"), [_cell(n, c) for n in NAMES for c in CONDITIONS])
def test_median_distance_ratio_is_within_5_percent(measured, name, cond):
    """The issue's bias criterion per person and condition: the median of measured / true
    distance within 0.95..1.05 (the box-size tracker was 0.70 on other people's photos)."""
    s = scores(measured[name, cond]["truth"], measured[name, cond]["got"])
    assert 0.95 <= s["median_ratio"] <= 1.05, s


@pytest.mark.slow
@pytest.mark.parametrize("name", NAMES)
def test_median_distance_ratio_per_person_is_within_5_percent(measured, name):
    """The issue's median criterion as it reads, per person: the median of measured / true
    distance over all conditions (84 frames) within 0.95..1.05 (measured 0.989 / 1.033 /
    0.995 / 0.964: astronaut, Hopper, luispedro, james). Per condition, above, two cells
    still miss."""
    s = pooled(measured, name)
    assert 0.95 <= s["median_ratio"] <= 1.05, s


# Measured share of all frames within the tolerances (seed 0), and what misses
SHARE_SHORT = {
    "hopper": "80 % (67 of 84): 8 turned 45 degrees 8-34 % long or aside (her painted nose), "
    "2 covered far faces not found, 1 covered far 8 % long and 15 cm aside, 2 frontal and 2 "
    "through the webcam far, 7-10 % long and 9-14 cm aside, 1 frontal at 1.0 m and 1 turned "
    "25 at 1.9 m 11 % long",
}


@pytest.mark.slow
@pytest.mark.parametrize(
    "name",
    [
        pytest.param(n, marks=pytest.mark.xfail(strict=True, reason=SHARE_SHORT[n]))
        if n in SHARE_SHORT
        else n
        for n in NAMES
    ],
)
def test_within_the_tolerances_in_95_percent_of_frames(measured, name):
    """The issue's accuracy criterion per person over all conditions: within 10 cm in x and
    y and 10 % in distance in at least 95 % of frames (a face not found counts as a miss)."""
    s = pooled(measured, name)
    assert s["within"] >= 0.95, s


@pytest.mark.slow
@pytest.mark.parametrize("name", NAMES)
def test_frontal_and_dim_faces_are_mostly_within_the_tolerances(measured, name):
    """A guard below the issue's 95 % (which Hopper misses, above): frontal and dim faces,
    and frontal ones through the emulated webcam, are all found, and of the three together
    (36 frames) at least 85 % within 10 cm in x and y and 10 % in distance (measured: the
    astronaut 36; Hopper 31, 9 / 12 / 10: far faces 7-10 % long and 9-14 cm aside, one at
    1.0 m 11 % long; luispedro 35, a far face 11 cm aside; james 34: 11 % short at 1.2 m,
    16 % long at 3.4 m). Pooled: a cell of 12 frames moves by 8 % with one frame (Hopper's
    frontal was 10 of 12 before the mirrored reading, :class:`YuNetConfig`, and is 44 of 48
    over seeds 0, 3, 7 and 11 with it against 43 of 48 without). The astronaut's dim face at
    3.4 m, which the frame scores about 0.6 (found or not by the host's floating point
    before), is found by the second look in its crop."""
    s = pooled(measured, name, ("frontal", "dim", "webcam"))
    assert s["found"] == 1.0 and s["within"] >= 0.85, s


@pytest.mark.slow
def test_viewers_watching_the_picture_are_all_found_and_ranged_as_facing_the_camera(measured):
    """A head facing a point of the picture nods against the camera above the screen by up
    to 30 degrees; the eyes' separation does not shorten with a nod: every face is found and
    its median distance ratio is no farther from 1 than the same person's facing the camera,
    give or take 3 % (measured 0.970 / 1.028 / 0.982 / 0.978 watching against 0.980 / 1.037 /
    0.962 / 0.946 frontal: astronaut, Hopper, luispedro, james)."""
    for name in NAMES:
        w = scores(measured[name, "watching"]["truth"], measured[name, "watching"]["got"])
        f = scores(measured[name, "frontal"]["truth"], measured[name, "frontal"]["got"])
        assert w["found"] == 1.0, (name, w)
        assert abs(w["median_ratio"] - 1.0) < abs(f["median_ratio"] - 1.0) + 0.03, (name, w, f)


@pytest.fixture(scope="module")
def tracked_covered():
    return measure_tracked("occluded")


@pytest.mark.slow
def test_a_tracked_face_is_followed_behind_a_hand(measured, tracked_covered):
    """A viewer already tracked who raises a hand over mouth and chin: the pipeline looks
    for the face again in an enlarged crop where it was, which finds what the whole-frame
    search misses (measured, the same poses: the astronaut's and Hopper's single frames 75 %
    and 83 % found, luispedro's and james's 100 %; tracked, every one)."""
    for name in ("astronaut", "hopper"):  # the others' covered faces: found in every frame
        alone = scores(measured[name, "occluded"]["truth"], measured[name, "occluded"]["got"])
        s = scores(tracked_covered[name]["truth"], tracked_covered[name]["got"])
        assert alone["found"] < 1.0, alone  # the bias this is about: whole-frame misses
        assert s["found"] == 1.0, (name, s)


@pytest.mark.slow
@pytest.mark.parametrize(
    "name",
    [
        "astronaut",
        "hopper",
        "luispedro",
        "james",
    ],
)
def test_a_tracked_face_behind_a_hand_is_mostly_within_the_tolerances(tracked_covered, name):
    """The faces followed behind a hand: at least 80 % within 10 cm in x and y and 10 % in
    distance (measured 92 / 83 / 92 / 92 %, median distance ratio 0.952 / 1.043 / 0.998 /
    0.954: astronaut, Hopper, luispedro, james)."""
    s = scores(tracked_covered[name]["truth"], tracked_covered[name]["got"])
    assert s["within"] >= 0.8, (name, s)


@pytest.fixture(scope="module")
def turning_45():
    """:func:`measure_turning` at 45 degrees, 6 walks a person: face height on, off."""
    return measure_turning(45.0, n=6), measure_turning(45.0, n=6, face_height=False)


@pytest.mark.slow
def test_a_viewer_who_turns_while_watching_is_ranged_by_their_face_height(turning_45):
    """Viewers who watch the picture, then turn their heads 45 degrees while walking
    (:func:`measure_turning`, 6 walks a person). A nodding head's nose reads a smaller turn
    than a head facing the camera, so the eyes alone range luispedro long (median 1.120, 22 %
    within 10 cm and 10 %); the face height his track learned while he faced the screen
    ranges him 1.042, 83 % within. For no one does it range farther from the truth than the
    eyes alone by more than 1 % (medians astronaut 1.085 / 1.183, Hopper 1.164 / 1.271, james
    0.966 / 1.063, on / off; over 12 walks james reads 0.968 / 1.054)."""
    on, off = turning_45
    for name in NAMES:
        a = scores(on[name]["truth"], on[name]["got"])
        b = scores(off[name]["truth"], off[name]["got"])
        assert abs(a["median_ratio"] - 1.0) < abs(b["median_ratio"] - 1.0) + 0.01, (name, a, b)
    a = scores(on["luispedro"]["truth"], on["luispedro"]["got"])
    b = scores(off["luispedro"]["truth"], off["luispedro"]["got"])
    assert b["median_ratio"] > 1.05, b  # the bias this is about
    assert abs(a["median_ratio"] - 1.0) < 0.05 and a["within"] >= b["within"] + 0.25, (a, b)


@pytest.mark.slow
@pytest.mark.parametrize(
    "name",
    [
        pytest.param(
            n,
            marks=pytest.mark.xfail(
                strict=True,
                reason=f"measured {m}: the painted nose of her photograph, taken frontal, "
                "lags the turn past what the ranging allows (the table's turned 45)",
            ),
        )
        for n, m in (("astronaut", "1.085, 67 % within"), ("hopper", "1.164, 39 % within"))
    ]
    + ["luispedro", "james"],
)
def test_a_viewer_turning_while_watching_is_ranged_within_5_percent(turning_45, name):
    """The issue's median criterion for viewers who watch the picture and turn 45 degrees,
    with the face height their track learned (measured: luispedro 1.042, james 0.966)."""
    s = scores(turning_45[0][name]["truth"], turning_45[0][name]["got"])
    assert s["found"] == 1.0 and 0.95 <= s["median_ratio"] <= 1.05, (name, s)


def side_by_side(k: int, frames: int = 12) -> np.ndarray:
    """k people (k <= 3) walking slowly side by side at 1.5..3 m, 10 frames/s: true eyes
    (frames, k, 3)."""
    t = np.arange(frames) / 10.0
    starts = np.array([[-0.6, 0.15, 1.6], [0.5, 0.2, 2.4], [0.05, 0.1, 3.0]])[:k]
    return starts[None] + 0.25 * t[:, None, None] * np.array([1.0, 0.0, -0.3])


def crossing(frames: int = 20) -> np.ndarray:
    """Two people crossing, 10 frames/s: one from the left at 1.4 m, one from the right at
    2.6 m, 1 m/s each way, passing each other in the camera's view half-way."""
    t = np.arange(frames) / 10.0 - 1.0
    a = np.stack([0.8 * t, np.full_like(t, 0.15), np.full_like(t, 1.4)], axis=-1)
    b = np.stack([-1.2 * t, np.full_like(t, 0.2), np.full_like(t, 2.6)], axis=-1)
    return np.stack([a, b], axis=1)


def crowd(truth: np.ndarray, seed: int = 0) -> list[dict[int, np.ndarray]]:
    """People at ``truth`` (frames, k, 3) (k <= 3: astronaut, hopper, luispedro), drawn
    near over far, tracked with ``--faces all`` at 10 frames/s: per frame the tracks seen in
    it ({track id: eye (3,)})."""
    dev = walk_camera()
    back = background(dev.resolution, seed)
    rng = np.random.default_rng(seed)
    p = np.asarray(dev.position)
    who = people()[: truth.shape[1]]
    images = []
    for row in truth:
        f = back
        for i in np.argsort(-np.linalg.norm(row - p, axis=1)):  # far to near
            f = render_person(f, dev, who[i], row[i])
        images.append(finish(f, rng))
    opts = TrackOptions(tracker=TrackerConfig(faces="all"))
    pipeline = Pipeline(ArraySource(images, 10.0), dev, opts)
    seen = []
    for fr in pipeline.source:
        published = pipeline.step(fr).eyes
        assert len(published) == max(1, len(pipeline.tracker.tracks))
        seen.append({tr.id: tr.eye for tr in pipeline.tracker.tracks if tr.seen == fr.t})
    pipeline.close()
    return seen


def separate_share(truth: np.ndarray, seen: list[dict[int, np.ndarray]]) -> float:
    """The share of frames in which every person has a track of their own (the assignment
    of tracks to people by least total distance pairs each within 25 % of their distance
    from the camera), nobody else is seen, and each person keeps the track id they had in
    the first frame."""
    from scipy.optimize import linear_sum_assignment

    p = np.asarray(walk_camera().position)
    first: dict[int, int] | None = None
    good = 0
    for row, tracks in zip(truth, seen, strict=True):
        if len(tracks) != len(row):
            continue
        ids = list(tracks)
        eyes = np.asarray([tracks[i] for i in ids])
        cost = np.linalg.norm(row[:, None] - eyes[None], axis=2)
        r, c = linear_sum_assignment(cost)
        if not np.all(cost[r, c] < 0.25 * np.linalg.norm(row[r] - p, axis=1)):
            continue
        who = {int(i): ids[j] for i, j in zip(r, c, strict=True)}
        first = who if first is None else first
        good += int(who == first)
    return good / len(truth)


@pytest.mark.slow
@pytest.mark.parametrize("k", [2, 3])
def test_two_and_three_viewers_are_separate_and_stable(k):
    truth = side_by_side(k)
    assert separate_share(truth, crowd(truth)) >= 0.95


@pytest.mark.slow
def test_two_viewers_crossing_keep_their_identities():
    """Two people cross (the nearer passes in front of the farther): each keeps its track
    id in every frame where both are seen; the farther one is hidden in at most the frame
    where they overlap (measured: 19 of 20 frames separate and stable)."""
    truth = crossing()
    assert separate_share(truth, crowd(truth)) >= 0.9


if __name__ == "__main__":  # the table of the report
    res = measure()
    for (name, cond), v in res.items():
        s = scores(v["truth"], v["got"])
        print(f"{name:10s} {cond:10s} found {s['found']:.2f} within {s['within']:.2f} "
              f"median ratio {s['median_ratio']:.3f}")  # fmt: skip
    for cond in ("occluded", "turned 45"):
        for name, v in measure_tracked(cond).items():
            s = scores(v["truth"], v["got"])
            print(f"{name:10s} {cond:10s} tracked: found {s['found']:.2f} within "
                  f"{s['within']:.2f} median ratio {s['median_ratio']:.3f}")  # fmt: skip
    for deg in (0.0, 25.0, 45.0):
        for on in (True, False):
            for name, v in measure_turning(deg, face_height=on).items():
                s = scores(v["truth"], v["got"])
                print(f"{name:10s} turning {deg:.0f} face height {'on ' if on else 'off'}: "
                      f"found {s['found']:.2f} within {s['within']:.2f} "
                      f"median ratio {s['median_ratio']:.3f}")  # fmt: skip
    for k in (2, 3):
        truth = side_by_side(k)
        share = separate_share(truth, crowd(truth))
        print(f"{k} viewers: separate and stable in {share:.2f} of frames")
    share = separate_share(crossing(), crowd(crossing()))
    print(f"2 viewers crossing: separate and stable in {share:.2f} of frames")
