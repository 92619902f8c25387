"""scripts/fetch_scan.py: the tests' scanned head, taken from menpo3d's source archive."""

from __future__ import annotations

import pytest

from tests.support.scripts import load_script


def _script():
    return load_script("scripts/fetch_scan.py")


def test_the_fetched_files_are_the_published_ones():
    """The set-up fetched them (scripts/setup.sh): each file as its SHA-256 says."""
    fetch = _script()
    assert fetch.damaged() == [], f"run: python scripts/fetch_scan.py ({fetch.DEST})"


def test_a_missing_or_changed_file_is_reported(tmp_path):
    fetch = _script()
    assert sorted(fetch.damaged(tmp_path)) == sorted(n for n, _ in fetch.MEMBERS.values())
    for name, _ in fetch.MEMBERS.values():
        (tmp_path / name).write_bytes((fetch.DEST / name).read_bytes())
    assert fetch.damaged(tmp_path) == []
    with open(tmp_path / "james.obj", "ab") as fh:
        fh.write(b"# one more line\n")
    assert fetch.damaged(tmp_path) == ["james.obj"]


def test_check_reports_without_fetching(tmp_path, monkeypatch, capsys):
    fetch = _script()
    monkeypatch.setattr(fetch, "DEST", tmp_path / "absent")
    assert fetch.main(["--check"]) == 1
    assert "missing or damaged" in capsys.readouterr().err
    assert not (tmp_path / "absent").exists()


@pytest.mark.parametrize("argv", [["--fetch"], ["a", "b"]])
def test_an_unknown_argument_is_refused(argv, capsys):
    assert _script().main(argv) == 2
    assert "Usage" in capsys.readouterr().err
