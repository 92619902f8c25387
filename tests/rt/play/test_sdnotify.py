"""The player's systemd notifications (rt/play/sdnotify.py) and the example unit file."""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from viewcomp.rt.play.sdnotify import Notifier

ROOT = Path(__file__).resolve().parents[3]
UNIT = ROOT / "examples/viewcomp-player.service"


def _listener(tmp_path: Path) -> tuple[socket.socket, str]:
    path = str(tmp_path / "notify")
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    sock.bind(path)
    sock.settimeout(2.0)
    return sock, path


def test_outside_systemd_every_call_does_nothing() -> None:
    n = Notifier({})
    assert not n.enabled
    assert not n.ready("up") and not n.status("x") and not n.watchdog() and not n.stopping()
    n.close()


def test_ready_status_and_stopping_reach_the_socket(tmp_path: Path) -> None:
    sock, path = _listener(tmp_path)
    with sock:
        n = Notifier({"NOTIFY_SOCKET": path})
        assert n.enabled and n.watchdog_interval is None
        assert n.ready("playing clip.mp4")
        assert sock.recv(4096) == b"READY=1\nSTATUS=playing clip.mp4"
        assert n.status("blackout")
        assert sock.recv(4096) == b"STATUS=blackout"
        assert n.stopping()
        assert sock.recv(4096) == b"STOPPING=1"
        n.close()


def test_abstract_namespace_address() -> None:
    name = f"viewcomp-test-{os.getpid()}"
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    sock.bind("\0" + name)
    sock.settimeout(2.0)
    with sock:
        n = Notifier({"NOTIFY_SOCKET": "@" + name})
        assert n.ready()
        assert sock.recv(4096) == b"READY=1"
        n.close()


def test_watchdog_pings_at_half_its_interval(tmp_path: Path) -> None:
    sock, path = _listener(tmp_path)
    with sock:
        n = Notifier({"NOTIFY_SOCKET": path, "WATCHDOG_USEC": "10000000"})
        assert n.watchdog_interval == 10.0
        sent = [n.watchdog(now=t) for t in (100.0, 101.0, 104.9, 105.0, 107.0, 110.1)]
        assert sent == [True, False, False, True, False, True]
        assert [sock.recv(64) for _ in range(3)] == [b"WATCHDOG=1"] * 3
        n.close()


def test_watchdog_meant_for_another_process_is_ignored(tmp_path: Path) -> None:
    sock, path = _listener(tmp_path)
    with sock:
        env = {"NOTIFY_SOCKET": path, "WATCHDOG_USEC": "10000000", "WATCHDOG_PID": "1"}
        n = Notifier(env)
        assert n.watchdog_interval is None and not n.watchdog(now=0.0)
        n.close()


def test_a_vanished_socket_never_raises(tmp_path: Path) -> None:
    n = Notifier({"NOTIFY_SOCKET": str(tmp_path / "gone")})
    assert n.enabled and not n.ready()
    n.close()


def test_unit_file_restarts_except_on_bad_input_and_uses_notify() -> None:
    text = UNIT.read_text()
    for line in ("Type=notify", "RestartPreventExitStatus=2", "Restart=always", "WatchdogSec="):
        assert line in text, line
    assert "--no-stdin" in text  # a service has no terminal to read commands from


@pytest.mark.skipif(shutil.which("systemd-analyze") is None, reason="needs systemd-analyze")
def test_unit_file_passes_systemd_analyze_verify(tmp_path: Path) -> None:
    viewcomp = Path(sys.executable).parent / "viewcomp"
    if not viewcomp.exists():
        pytest.skip(f"no {viewcomp} (viewcomp not installed into this interpreter's folder)")
    unit = tmp_path / UNIT.name
    unit.write_text(UNIT.read_text().replace("/opt/viewcomp/.venv/bin/viewcomp", str(viewcomp)))
    out = subprocess.run(
        ["systemd-analyze", "verify", str(unit)], capture_output=True, text=True, timeout=60
    )
    assert out.returncode == 0, out.stdout + out.stderr
