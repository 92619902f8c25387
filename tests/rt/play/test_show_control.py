"""Show control of `viewcomp play` under a private Xvfb: OSC from python-osc, stdin, keys.

A controller thread drives a player over OSC (pause, resume, seek, next, previous, blackout,
the normalised angle) and asks for ``/viewcomp/status`` after each step; every reply is
checked against what the window shows: the framebuffer read back when that frame was drawn
must be the numpy reference's compensation of the frame at the reply's file and position,
for the reply's eye. Waits are bounded (a step that never happens fails); no timing is
asserted.
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from pythonosc.osc_message import OscMessage
from pythonosc.udp_client import SimpleUDPClient

from tests.support.calibrations import small_calibration
from tests.support.synthetic import make_test_video
from viewcomp.calib.model.reference import compensate
from viewcomp.rt.media.frames import Planes, yuv420p_to_rgb
from viewcomp.rt.media.video import VideoReader
from viewcomp.rt.play.xvfb import Xvfb, xvfb_available

pytestmark = pytest.mark.usefixtures("session_gl_current")

RATE = 30
GRID = (64, 32)
OUTLIERS = 6  # pixel-channels > 1 level from the reference per frame (see test_player.py)


@pytest.fixture(scope="module")
def display() -> Any:
    if not xvfb_available():
        if os.environ.get("VIEWCOMP_REQUIRE_GL") == "1":
            pytest.fail("Xvfb is not installed (VIEWCOMP_REQUIRE_GL=1)", pytrace=False)
        pytest.skip("Xvfb is not installed (Debian package xvfb)")
    with Xvfb((1280, 720)) as x:
        yield x.display


@pytest.fixture(scope="module")
def cal() -> Any:
    return small_calibration(*GRID, screen="magenta")


@pytest.fixture(scope="module")
def clips(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    folder = tmp_path_factory.mktemp("show")
    out = []
    for name, seconds in (("a.mp4", 4.0), ("b.mp4", 3.0)):
        make_test_video(str(folder / name), 128, 64, seconds=seconds, rate=RATE, audio=True)
        out.append(folder / name)
    return out


def decoded(path: Path) -> list[Planes]:
    """Every frame of a clip fitted to the grid, as the player's reader gives them."""
    with VideoReader(path, fit=GRID, audio="none") as r:
        return [p for p in r if isinstance(p, Planes)]


class Controller:
    """python-osc on one socket: sends to the player and receives its status replies."""

    def __init__(self, address: tuple[str, int]) -> None:
        self.client = SimpleUDPClient(*address)

    def close(self) -> None:
        self.client._sock.close()

    def send(self, address: str, *args: Any) -> None:
        self.client.send_message(address, list(args) if args else None)

    def status(self) -> dict[str, Any]:
        self.send("/viewcomp/status")
        msg = OscMessage(self.client.receive(timeout=10.0))
        assert msg.address == "/viewcomp/status"
        keys = ("file", "position", "paused", "angle", "x", "y", "z", "fps", "dropped",
                "blackout")  # fmt: skip
        assert len(msg.params) == len(keys)
        return dict(zip(keys, msg.params, strict=True))

    def until(self, cond: Any, what: str, limit: float = 20.0) -> dict[str, Any]:
        """Ask for the status until ``cond(status)``; fails after ``limit`` seconds."""
        end = time.monotonic() + limit
        while True:
            st = self.status()
            if cond(st):
                return st
            if time.monotonic() > end:
                raise AssertionError(f"{what}: never happened; last status {st}")
            time.sleep(0.05)


@pytest.mark.gl
def test_osc_show_control_with_status_checked_against_the_window(
    display: str, cal: Any, clips: list[Path]
) -> None:
    from viewcomp.rt.play.player import Player, PlayerOptions

    frames = {p.name: decoded(p) for p in clips}
    shots: dict[tuple[str, float], tuple[np.ndarray, Any]] = {}  # (file, time) -> last drawn
    lock = threading.Lock()
    presented: list[int] = [0]

    def on_frame(player: Any, f: Any) -> None:
        with lock:
            shots[(f.path.name, round(float(f.time), 4))] = (player.read_window(), f.record)
            presented[0] = player.stats.presented

    opts = PlayerOptions(windowed=True, audio=False, stdin_fd=None, max_seconds=120.0,
                         osc=("127.0.0.1", 0), eye_tau=0.0, loop=True,
                         norm_range=(30.0, 150.0))  # fmt: skip
    player = Player(cal, clips, opts, on_frame=on_frame)
    log: list[str] = []
    errors: list[BaseException] = []

    def window_matches(st: dict[str, Any]) -> None:
        """The frame on screen is the reference for the status's file, position and eye."""
        name = Path(st["file"]).name
        with lock:
            shot, record = shots[(name, round(float(st["position"]), 4))]
        eye = np.array([st["x"], st["y"], st["z"]])
        np.testing.assert_allclose(eye, record.eye, atol=1e-5)
        if st["blackout"]:
            assert int(shot.max()) == 0
            return
        times = np.array([p.time for p in frames[name]])
        k = int(np.argmin(np.abs(times - st["position"])))
        assert abs(times[k] - st["position"]) < 1e-3
        p = record.params
        want = compensate(p.model, yuv420p_to_rgb(frames[name][k]), eye, p.alpha, p.beta)
        d = np.abs(shot.astype(int) - want.astype(int))
        assert int((d > 1).sum()) <= OUTLIERS, (st, int(d.max()))

    def drive() -> None:
        while player.osc_address is None or presented[0] < 5:
            time.sleep(0.02)
        c = Controller(player.osc_address)
        try:
            st = c.until(lambda s: s["position"] > 0.2, "playing")
            assert st["paused"] == 0 and Path(st["file"]).name == "a.mp4"
            # normalised angle: 0.25 of 30..150 is 60 degrees
            c.send("/viewcomp/angle/norm", 0.25)
            st = c.until(lambda s: abs(s["angle"] - 60.0) < 1e-3, "angle/norm 0.25")
            window_matches(st)
            log.append("norm")
            # pause: the position and the picture hold
            c.send("/viewcomp/pause")
            st = c.until(lambda s: s["paused"] == 1, "pause")
            with lock:
                before = presented[0]
            time.sleep(0.5)
            st2 = c.status()
            assert st2["position"] == st["position"] and st2["paused"] == 1
            with lock:
                assert presented[0] == before  # no video frame presented while paused
            window_matches(st2)
            log.append("pause")
            # seek while paused: the frame at 2 s is shown, still paused
            c.send("/viewcomp/seek", 2.0)
            st = c.until(lambda s: abs(s["position"] - 2.0) < 0.6 / RATE, "seek 2.0")
            assert st["paused"] == 1
            window_matches(st)
            log.append("seek")
            # resume: playing on from 2 s
            c.send("/viewcomp/resume")
            st = c.until(lambda s: s["paused"] == 0 and s["position"] > 2.2, "resume")
            window_matches(st)
            log.append("resume")
            # next and previous files
            c.send("/viewcomp/next")
            st = c.until(lambda s: Path(s["file"]).name == "b.mp4", "next")
            window_matches(st)
            c.send("/viewcomp/previous")
            st = c.until(lambda s: Path(s["file"]).name == "a.mp4" and s["position"] < 1.0,
                         "previous")  # fmt: skip
            window_matches(st)
            log.append("next/previous")
            # blackout: the window is black, playback goes on underneath; then the picture
            c.send("/viewcomp/blackout", 1)
            st = c.until(lambda s: s["blackout"] == 1, "blackout 1")
            window_matches(st)
            c.send("/viewcomp/blackout", 0)
            st = c.until(lambda s: s["blackout"] == 0 and s["paused"] == 0, "blackout 0")
            window_matches(st)
            log.append("blackout")
            # malformed: dropped, the player answers on
            c.send("/viewcomp/seek", "soon")
            c.send("/viewcomp/blackout", 2)
            c.send("/viewcomp/angle/norm", 1.5)
            st = c.status()
            assert abs(st["angle"] - 60.0) < 1e-3
            log.append("malformed")
        except BaseException as exc:
            errors.append(exc)
        finally:
            c.close()
            player.stop()

    t = threading.Thread(target=drive, daemon=True)
    t.start()
    stats = player.run()
    t.join(timeout=30)
    print("\n" + stats.summary(), log)
    if errors:
        raise errors[0]
    assert log == ["norm", "pause", "seek", "resume", "next/previous", "blackout", "malformed"]
    assert stats.inputs["osc"].rejected == 3
    assert player.renderer is not None and player.renderer.live_objects() == 0


@pytest.mark.gl
def test_still_image_stays_up_and_keys_pause(display: str, cal: Any, tmp_path: Path) -> None:
    import cv2
    import glfw

    from viewcomp.rt.play.player import Player, PlayerOptions

    img = tmp_path / "still.png"
    cv2.imwrite(str(img), np.full((32, 64, 3), 200, np.uint8))
    seen: list[tuple[bool, float]] = []

    def on_frame(player: Any, f: Any) -> None:
        seen.append((player._paused, f.time))
        if len(seen) == 1:
            player._on_key(player._win, glfw.KEY_SPACE, 0, glfw.PRESS, 0)
            player._on_key(player._win, glfw.KEY_LEFT, 0, glfw.PRESS, 0)  # eye moves: redraw
        elif len(seen) == 2:
            player.stop()

    opts = PlayerOptions(windowed=True, audio=False, stdin_fd=None, max_seconds=60.0,
                         still_seconds=30.0, eye_tau=0.0)  # fmt: skip
    stats = Player(cal, [img], opts, on_frame=on_frame).run()
    assert seen == [(False, 0.0), (True, 0.0)]  # paused, then redrawn for the new eye
    assert stats.stills == 1 and stats.presented == 0
    assert "1 still image shown" in stats.summary() and "frames/s" not in stats.summary()


def test_folder_playlist_picks_up_new_files(tmp_path: Path) -> None:
    from viewcomp.rt.play.player import Player, expand_playlist

    (tmp_path / "a.mp4").write_bytes(b"")
    player = Player.__new__(Player)
    player._sources = [tmp_path]
    player.playlist = expand_playlist([tmp_path])
    (tmp_path / "b.png").write_bytes(b"")
    player._refresh_playlist()
    assert [p.name for p in player.playlist] == ["a.mp4", "b.png"]


# ----------------------------------------------------------------------- command line
@pytest.mark.gl
def test_cli_stdin_status_and_osc_feedback(display: str, cal: Any, clips: list[Path],
                                           tmp_path: Path) -> None:  # fmt: skip
    bundle = tmp_path / "screen.vcb"
    cal.save(bundle)
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", 0))
    rx.settimeout(30.0)
    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    probe.bind(("127.0.0.1", 0))
    port = probe.getsockname()[1]
    probe.close()
    p = subprocess.Popen(
        [sys.executable, "-m", "viewcomp", "play", str(bundle), str(clips[0]), "--windowed",
         "--no-audio", "--loop", "--eye-smooth", "0", "--norm-angle-range", "40:140",
         "--osc-feedback", f"127.0.0.1:{rx.getsockname()[1]}", "--feedback-every", "0.2",
         "--seconds", "60", "--osc", f"127.0.0.1:{port}"],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        msg = OscMessage(rx.recv(65536))  # pushed without being asked
        assert msg.address == "/viewcomp/status" and len(msg.params) == 10
        assert p.stdin is not None and p.stdout is not None
        # a type tag python-osc does not know: python-osc logs it, viewcomp must not show that
        rx.sendto(b"/viewcomp/angle\0,x\0\0\0\0\0\1", ("127.0.0.1", port))
        p.stdin.write("norm 0.2\npause\nbogus words\n")
        p.stdin.flush()
        time.sleep(0.5)
        p.stdin.write("status\n")
        p.stdin.flush()
        line = p.stdout.readline()
        assert line.startswith("status file=") and "paused=1" in line and "angle=60.00" in line
        p.send_signal(signal.SIGTERM)
        out, err = p.communicate(timeout=30)
    finally:
        rx.close()
        if p.poll() is None:
            p.kill()
    assert p.returncode == 0, err
    assert "video frames presented" in out
    assert "stdin: dropped: unknown command 'bogus'" in err
    assert "osc: dropped: /viewcomp/angle takes one number" in err
    assert all(line.startswith("viewcomp play: ") for line in err.splitlines()), err


@pytest.mark.gl
def test_embed_example_with_the_frame_in_a_host_texture(display: str) -> None:
    root = Path(__file__).resolve().parents[3]
    p = subprocess.run([sys.executable, str(root / "examples" / "embed_host.py"), "--frames",
                        "20", "--check", "--size", "320x240", "--texture"], capture_output=True,
                       text=True, timeout=120)  # fmt: skip
    print(p.stdout)
    assert p.returncode == 0, p.stderr
    assert "window vs numpy reference" in p.stdout


def test_dropped_frames_are_logged_as_they_happen_rate_limited(caplog: Any) -> None:
    import logging
    import math

    from viewcomp.rt.play.player import DROP_LOG_PERIOD, Player, PlayerStats

    player = Player.__new__(Player)
    player.stats = PlayerStats()
    player._drops_unlogged, player._drop_logged_at = 0, -math.inf
    player._file, player._origin = (0, Path("a.mp4")), 100.0
    with caplog.at_level(logging.WARNING, logger="viewcomp.rt.play.player"):
        player._dropped(1000.0, 101.0)  # the first: at once
        player._dropped(1001.0, 101.04)  # within the period: counted
        player._dropped(1000.0 + DROP_LOG_PERIOD, 102.0)  # the period is over: both
    msgs = [r.getMessage() for r in caplog.records]
    assert len(msgs) == 2, msgs
    assert msgs[0].startswith("dropped 1 late frame (a.mp4 at 1.00 s; 1 in all)")
    assert msgs[1].startswith("dropped 2 late frames (a.mp4 at 2.00 s; 3 in all)")
    assert player.stats.dropped == 3
