"""README.md's typical session, command for command, as a user runs it after the set-up.

The commands are read from README.md's first ``sh`` block after "A typical session" and run
verbatim with bash, in a folder laid out as a fresh clone after ``bash scripts/setup.sh``
(its ``.venv`` and ``examples``). Every command must succeed and print only viewcomp's own
words (no other library's log lines, no traceback); the files they promise must exist.
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def session_commands() -> list[str]:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    start = text.index("A typical session")
    block = re.search(r"```sh\n(.*?)```", text[start:], re.S)
    assert block is not None, "README.md: no ```sh block after 'A typical session'"
    lines = [ln.split("  #")[0].strip() for ln in block.group(1).splitlines()]
    return [ln for ln in lines if ln and not ln.startswith("#")]


def test_the_session_is_found_and_uses_the_installed_command() -> None:
    cmds = session_commands()
    assert len(cmds) >= 5
    assert all(c.startswith((".venv/bin/viewcomp ", ".venv/bin/python ")) for c in cmds), cmds


@pytest.mark.slow
def test_readme_typical_session_runs_verbatim(tmp_path: Path) -> None:
    if not (ROOT / ".venv" / "bin" / "viewcomp").exists():
        pytest.fail("run `bash scripts/setup.sh` first: .venv/bin/viewcomp is missing")
    (tmp_path / ".venv").symlink_to(ROOT / ".venv")
    (tmp_path / "examples").symlink_to(ROOT / "examples")
    foreign = re.compile(r"\[ ?(WARN|ERROR|INFO)[:\]]|WARNING:root|Traceback|^\s*warnings?\.warn")
    for cmd in session_commands():
        r = subprocess.run(["bash", "-c", cmd], cwd=tmp_path, capture_output=True, text=True,
                           timeout=900)  # fmt: skip
        print(f"$ {cmd}\n{r.stdout[-400:]}")
        assert r.returncode == 0, f"{cmd}\n{r.stderr[-2000:]}"
        for line in (r.stdout + r.stderr).splitlines():
            assert not foreign.search(line), f"{cmd}: not viewcomp's words: {line}"
    for name in ("photo-60.png", "photo-seen-60.png", "clip-comp.mp4", "magenta.vcb",
                 "report/report.md"):  # fmt: skip
        assert (tmp_path / name).is_file(), name
