"""Fetches the tests' scanned head: menpo3d's ``james`` (a textured 3-D face scan with 68
landmarks, BSD-licensed, in menpo3d 0.8.6's source package on PyPI), checked by SHA-256.

The package itself is not installed (it needs a compiler and Mayavi); only its data files
and its licence are taken from the archive, into ``.cache/menpo3d-0.8.6/`` (ignored by git).
Safe to run again: files already there and intact are kept. ``scripts/setup.sh`` runs it.

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
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
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


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def damaged(dest: Path | None = None) -> list[str]:
    """The files of :data:`MEMBERS` missing from ``dest`` (None: :data:`DEST`) or not as
    published."""
    dest = DEST if dest is None else dest
    return [
        name
        for name, digest in MEMBERS.values()
        if not (dest / name).is_file() or _sha256(dest / name) != digest
    ]


def fetch(dest: Path | None = None) -> None:
    """Downloads the archive, checks it and writes the files of :data:`MEMBERS` into
    ``dest`` (None: :data:`DEST`; all or none: unpacked beside it, then moved in place)."""
    dest = DEST if dest is None else dest
    dest.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=dest.parent) as tmp:
        archive = Path(tmp) / "menpo3d.tar.gz"
        with urllib.request.urlopen(URL, timeout=60) as resp, open(archive, "wb") as out:
            size = 0
            while chunk := resp.read(1 << 20):
                size += len(chunk)
                if size > ARCHIVE_MAX:
                    raise OSError(f"{URL} is larger than {ARCHIVE_MAX} bytes")
                out.write(chunk)
        if _sha256(archive) != ARCHIVE_SHA256:
            raise OSError(f"{URL} does not have the published SHA-256 {ARCHIVE_SHA256}")
        staged = Path(tmp) / "files"
        staged.mkdir()
        with tarfile.open(archive, "r:gz") as tar:
            for member, (name, _) in MEMBERS.items():
                src = tar.extractfile(tar.getmember(member))  # regular files only
                if src is None:
                    raise OSError(f"{member} in {URL} is not a file")
                with src, open(staged / name, "wb") as out:
                    shutil.copyfileobj(src, out)
        bad = damaged(staged)
        if bad:
            raise OSError(f"{', '.join(bad)} in {URL} differ from the expected files")
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
