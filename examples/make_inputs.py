"""Inputs to try viewcomp with: a photograph, a 4-second clip and a viewer's track.

    .venv/bin/python examples/make_inputs.py [FOLDER]

writes ``photo.jpg`` (640x320), ``clip.mp4`` (4 s, 25 frames/s, a slow pan across natural
photographs, with a 440 Hz tone) and ``angles.csv`` (a viewer walking from 60 to 120 degrees
and back) into FOLDER (default: the current folder), the files README.md's typical session
uses. Every file is written atomically; existing ones are replaced.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from viewcomp.calib.eval.testimages import natural_images
from viewcomp.calib.io.atomic import write_bytes_atomic, write_text_atomic
from viewcomp.commands.demo import WALK_CSV, write_pan_clip


def main() -> int:
    import cv2

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("folder", nargs="?", default=".", help="where to write (default .)")
    out = Path(ap.parse_args().folder)
    out.mkdir(parents=True, exist_ok=True)
    images = list(natural_images(640, 320).values())
    ok, jpeg = cv2.imencode(".jpg", images[0][..., ::-1], [cv2.IMWRITE_JPEG_QUALITY, 92])
    if not ok:
        raise SystemExit("cannot encode the photograph as JPEG")
    write_bytes_atomic(out / "photo.jpg", jpeg.tobytes())
    write_pan_clip(out / "clip.mp4", images, seconds=4.0, rate=25)
    write_text_atomic(out / "angles.csv", WALK_CSV)
    print(f"wrote {out / 'photo.jpg'}, {out / 'clip.mp4'} and {out / 'angles.csv'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
