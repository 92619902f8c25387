"""scripts/setup.sh: its apt-get waits (bounded) while another process holds apt's and dpkg's
locks, as unattended upgrades do on a fresh machine, instead of failing at once with apt's
exit 100; `--runtime` installs viewcomp without the test tools (a kiosk)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
LOCKS = ("/var/lib/dpkg/lock-frontend", "/var/lib/dpkg/lock", "/var/lib/apt/lists/lock")

# Holds apt's locks the way apt does (fcntl record locks) for argv[1] seconds.
HOLDER = """
import fcntl, os, sys, time
fds = []
for p in sys.argv[2:]:
    fd = os.open(p, os.O_RDWR | os.O_CREAT, 0o640)
    fcntl.lockf(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    fds.append(fd)
print("holding", flush=True)
time.sleep(float(sys.argv[1]))
"""

pytestmark = pytest.mark.slow
needs_apt = pytest.mark.skipif(
    shutil.which("apt-get") is None or os.geteuid() != 0,
    reason="needs Debian's apt-get and root (to take apt's locks)",
)


def _hold(seconds: float) -> subprocess.Popen[str]:
    holder = subprocess.Popen(
        [sys.executable, "-c", HOLDER, str(seconds), *LOCKS], stdout=subprocess.PIPE, text=True
    )
    assert holder.stdout is not None and holder.stdout.readline().strip() == "holding"
    return holder


def _release(holder: subprocess.Popen[str]) -> None:
    holder.kill()
    holder.wait()
    if holder.stdout is not None:
        holder.stdout.close()


def _installed_package() -> str:
    """A package that is installed (apt-get install of it changes nothing but takes the locks)."""
    for name in ("ffmpeg", "libegl1", "bash"):
        out = subprocess.run(
            ["dpkg-query", "-W", "-f=${db:Status-Status}", name], capture_output=True, text=True
        )
        if out.stdout == "installed":
            return name
    pytest.skip("none of ffmpeg, libegl1, bash is installed")


@needs_apt
def test_apt_get_waits_for_a_held_lock() -> None:
    pkg = _installed_package()
    holder = _hold(6.0)
    try:
        start = time.monotonic()
        out = subprocess.run(
            ["bash", str(ROOT / "scripts/apt_get.sh"), "install", "-y", "-q", pkg],
            capture_output=True,
            text=True,
            env={**os.environ, "APT_LOCK_WAIT": "60"},
            timeout=120,
        )
        waited = time.monotonic() - start
    finally:
        _release(holder)
    assert out.returncode == 0, out.stdout + out.stderr
    # it really met the lock: it could not finish before the holder let go
    assert waited >= 4.0, f"finished after {waited:.1f} s although the lock was held for 6 s"


@needs_apt
def test_apt_get_gives_up_after_the_bound_with_a_reason() -> None:
    pkg = _installed_package()
    holder = _hold(30.0)
    try:
        out = subprocess.run(
            ["bash", str(ROOT / "scripts/apt_get.sh"), "install", "-y", "-q", pkg],
            capture_output=True,
            text=True,
            env={**os.environ, "APT_LOCK_WAIT": "2"},
            timeout=60,
        )
    finally:
        _release(holder)
    assert out.returncode != 0
    assert "still locked after 2 s" in out.stderr and "APT_LOCK_WAIT" in out.stderr


@pytest.mark.skipif(shutil.which("git") is None, reason="needs git to clone the repository")
def test_runtime_setup_installs_viewcomp_without_test_tools(tmp_path: Path) -> None:
    if not (ROOT / ".git").exists():
        pytest.skip("not a git checkout: nothing to clone")
    clone = tmp_path / "kiosk"
    subprocess.run(["git", "clone", "-q", str(ROOT), str(clone)], check=True, timeout=120)
    out = subprocess.run(
        ["bash", "scripts/setup.sh", "--runtime"],
        cwd=clone,
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert out.returncode == 0, out.stdout + out.stderr
    py = clone / ".venv/bin/python"
    # run from outside any checkout: `python -c` puts the working folder first on sys.path
    ok = subprocess.run([str(py), "-c", "import viewcomp.cli"], cwd=tmp_path, timeout=120)
    assert ok.returncode == 0
    for tool in ("pytest", "ruff", "mypy"):
        found = subprocess.run(
            [str(py), "-c", f"import {tool}"], cwd=tmp_path, capture_output=True, timeout=60
        )
        assert found.returncode != 0, f"a runtime-only set-up installed {tool}"
    assert not (clone / ".venv/bin/pytest").exists()
