"""The documentation points inside the repository and names what exists (no GL).

- README.md, docs/*.md and the sources cite the model and the interfaces as docs/MODEL.md
  and docs/INTERFACES.md, never a path outside the repository.
- Every dotted ``viewcomp.x.y`` path in README.md and docs/*.md imports (a trailing part may
  be an attribute of the module), and every file path they quote exists.
- docs/INTERFACES.md documents exactly the options each command's ``--help`` shows.
"""

from __future__ import annotations

import argparse
import importlib
import re
import tomllib
from pathlib import Path

import pytest

from viewcomp.cli import build_parser

ROOT = Path(__file__).resolve().parents[2]
SOURCE_DIRS = ("calib", "rt", "shaders", "viewcomp", "examples", "bench", "scripts")
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]

# A reference to the model or the interfaces that is not docs/MODEL.md or docs/INTERFACES.md,
# or any path into a sibling folder of the repository.
BAD_REFERENCE = re.compile(
    r"(?<!docs/)\b(?:MODEL|INTERFACES)\.md|\.\./(?:shared|paper)\b|/work/|\bshared/docs/"
)
DOTTED = re.compile(r"\bviewcomp(?:\.[A-Za-z_]\w*)+")
QUOTED_FILE = re.compile(
    r"`((?:calib|rt|shaders|viewcomp|tests|bench|docs|examples|scripts)/[\w./-]+"
    r"\.(?:py|glsl|md|sh|toml|json))(?:::\w+)?`"
)


def _documents_and_sources() -> list[Path]:
    files = list(DOCS)
    for folder in SOURCE_DIRS:
        files += sorted(p for p in (ROOT / folder).rglob("*") if p.suffix in (".py", ".glsl"))
    return files


def _lines(path: Path) -> list[tuple[int, str]]:
    return list(enumerate(path.read_text(encoding="utf-8").splitlines(), start=1))


def test_the_scanned_files_exist():
    """The scans below see the documents and the sources (a wrong ROOT would pass them)."""
    names = {p.relative_to(ROOT).as_posix() for p in _documents_and_sources()}
    assert {"README.md", "docs/MODEL.md", "docs/INTERFACES.md", "calib/world/rig.py"} <= names
    assert "shaders/compensate.frag.glsl" in names


def test_references_point_into_the_repository():
    bad = [
        f"{path.relative_to(ROOT)}:{n}: {line.strip()}"
        for path in _documents_and_sources()
        for n, line in _lines(path)
        if BAD_REFERENCE.search(line)
    ]
    assert not bad, (
        "cite docs/MODEL.md and docs/INTERFACES.md of this repository, no path outside it:\n"
        + "\n".join(bad)
    )


def test_bad_reference_pattern():
    """The pattern used above finds what it must and passes what it may."""
    for text in ("see MODEL.md", "(INTERFACES.md)", "../shared/docs/X.md", "../paper/p", "/work/x"):
        assert BAD_REFERENCE.search(text), text
    for text in (
        "see docs/MODEL.md section 2",
        "docs/INTERFACES.md of viewcomp",
        "docs/RUNTIME.md",
    ):
        assert not BAD_REFERENCE.search(text), text


def resolve(dotted: str) -> object:
    """The object a dotted path names: the longest importable module prefix, then attributes.

    Raises:
        LookupError: no prefix imports, or an attribute is missing.
    """
    parts = dotted.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj: object = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        for attr in parts[i:]:
            if not hasattr(obj, attr):
                raise LookupError(f"{'.'.join(parts[:i])} has no attribute path {parts[i:]}")
            obj = getattr(obj, attr)
        return obj
    raise LookupError(f"no part of {dotted} imports")


def test_resolve():
    assert resolve("viewcomp.calib.model.reference.compensate").__name__ == "compensate"
    with pytest.raises(LookupError):
        resolve("viewcomp.calib.reference")
    with pytest.raises(LookupError):
        resolve("viewcomp.rt.compensator.Compensator")


def test_module_paths_in_the_docs_import():
    found: dict[str, list[str]] = {}
    for path in DOCS:
        for n, line in _lines(path):
            for m in DOTTED.finditer(line):
                found.setdefault(m.group(0), []).append(f"{path.relative_to(ROOT)}:{n}")
    assert "viewcomp.rt.play.embed.LiveRenderer" in found  # the scan sees README.md
    bad = []
    for name, where in sorted(found.items()):
        try:
            resolve(name)
        except LookupError as exc:
            bad.append(f"{name} ({', '.join(where)}): {exc}")
    assert not bad, "module paths in the docs that do not import:\n" + "\n".join(bad)


def test_file_paths_in_the_docs_exist():
    missing = [
        f"{path.relative_to(ROOT)}:{n}: {m.group(1)}"
        for path in DOCS
        for n, line in _lines(path)
        for m in QUOTED_FILE.finditer(line)
        if not (ROOT / m.group(1)).is_file()
    ]
    assert not missing, "files named in the docs that do not exist:\n" + "\n".join(missing)


# ------------------------------------------------------------------ commands and options

OPTION = re.compile(r"(?<![\w-])--[a-z][a-z0-9-]*")
SECTION = re.compile(r"^### `viewcomp ([a-z-]+)")


def documented_options() -> dict[str, set[str]]:
    """Command -> the ``--options`` written in its ``### `viewcomp CMD ...``` section."""
    out: dict[str, set[str]] = {}
    command = None
    for _n, line in _lines(ROOT / "docs" / "INTERFACES.md"):
        m = SECTION.match(line)
        if m:
            command = m.group(1)
            out[command] = set()
        elif line.startswith("#"):
            command = None
        if command is not None:
            out[command].update(OPTION.findall(line))
    return out


def command_parsers() -> dict[str, argparse.ArgumentParser]:
    """Command name -> its argument parser, as ``viewcomp`` builds them."""
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


def long_options(parser: argparse.ArgumentParser) -> set[str]:
    """Every ``--option`` a parser accepts, ``--help`` aside."""
    return {s for a in parser._actions for s in a.option_strings if s.startswith("--")} - {"--help"}


def test_interfaces_documents_every_command_and_option():
    doc = documented_options()
    parsers = command_parsers()
    assert sorted(doc) == sorted(parsers), "docs/INTERFACES.md needs one section per command"
    assert "--paper-fit" in doc["calibrate"]  # the sections' tables are read
    problems = []
    for command, written in sorted(doc.items()):
        actual = long_options(parsers[command])
        if written - actual:
            problems.append(f"{command}: documented but not accepted: {sorted(written - actual)}")
        if actual - written:
            problems.append(f"{command}: accepted but not documented: {sorted(actual - written)}")
    assert not problems, "docs/INTERFACES.md and the command line differ:\n" + "\n".join(problems)


def test_pyproject_lists_every_package():
    """`pip install .` (docs/INTERFACES.md, Packaging) installs every sub-package: setuptools
    installs only the packages listed in pyproject.toml."""
    meta = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    setup = meta["tool"]["setuptools"]
    listed = set(setup["packages"])
    found = set()
    for name, folder in setup["package-dir"].items():
        for init in (ROOT / folder).rglob("__init__.py"):
            rel = init.parent.relative_to(ROOT / folder).parts
            found.add(".".join((name, *rel)))
    assert {"viewcomp.commands", "viewcomp.calib.world", "viewcomp.rt.gl"} <= found
    assert found == listed, f"add to pyproject.toml packages: {sorted(found - listed)}; " + (
        f"remove: {sorted(listed - found)}"
    )
