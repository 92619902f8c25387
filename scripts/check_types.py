"""Type-check viewcomp.calib and viewcomp.rt with mypy (settings: ``[tool.mypy]`` of
pyproject.toml).

The packages live in folders that are not their import names (``calib/`` is
``viewcomp.calib``, pyproject.toml's ``package-dir``), and the editable install maps them
with an import hook that mypy cannot follow. So this script lays out the import names as
symbolic links in ``build/typecheck/`` (``viewcomp/calib`` -> ``calib/``, and so on) and runs
mypy there; the errors name the files by those paths.

Usage: ``python scripts/check_types.py [mypy options]`` (exit status: mypy's).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FARM = ROOT / "build" / "typecheck"
CHECKED = ("viewcomp.calib", "viewcomp.rt")


def link_farm() -> Path:
    """``build/typecheck/viewcomp/...`` as links to the package folders; returns its root."""
    mapping = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"][
        "package-dir"
    ]
    if FARM.exists():
        shutil.rmtree(FARM)
    top = FARM / "viewcomp"
    top.mkdir(parents=True)
    for entry in (ROOT / mapping["viewcomp"]).iterdir():
        if entry.name != "__pycache__":
            (top / entry.name).symlink_to(entry)
    for name, folder in mapping.items():
        if name != "viewcomp":
            (FARM / name.replace(".", "/")).symlink_to(ROOT / folder)
    return FARM


def main(argv: list[str]) -> int:
    farm = link_farm()
    env = dict(os.environ, MYPYPATH=str(farm))
    args = [sys.executable, "-m", "mypy", "--config-file", str(ROOT / "pyproject.toml")]
    for pkg in CHECKED:
        args += ["-p", pkg]
    return subprocess.call([*args, *argv], env=env, cwd=ROOT)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
