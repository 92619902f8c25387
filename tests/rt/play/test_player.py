"""`viewcomp play` under a private Xvfb: playback, live input, fuzzing, CLI, embedding.

Every test here starts and stops its own Xvfb (one per module). Without Xvfb they skip,
except under VIEWCOMP_REQUIRE_GL=1, where they fail. Timing is printed, never asserted
(bench/bench_player_inputs.py measures the main loop's longest gap while fuzzed); the input
contract is counted in presented frames (a new angle shows within two of them).
"""

from __future__ import annotations

import itertools
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from pythonosc.osc_message_builder import OscMessageBuilder

from tests.support.calibrations import small_calibration
from tests.support.synthetic import make_test_video
from viewcomp.calib.model.reference import compensate
from viewcomp.rt.media.audio import open_alsa
from viewcomp.rt.media.frames import yuv420p_to_rgb
from viewcomp.rt.play.xvfb import Xvfb, xvfb_available

pytestmark = pytest.mark.usefixtures("session_gl_current")

ROOT = Path(__file__).resolve().parents[3]
RATE = 30


def _need(what: str) -> None:
    if os.environ.get("VIEWCOMP_REQUIRE_GL") == "1":
        pytest.fail(f"{what} (VIEWCOMP_REQUIRE_GL=1)", pytrace=False)
    pytest.skip(what)


@pytest.fixture(scope="module")
def display() -> Any:
    """A private 1280x720 Xvfb; DISPLAY points at it while the module's tests run."""
    if not xvfb_available():
        _need("Xvfb is not installed (Debian package xvfb)")
    with Xvfb((1280, 720)) as x:
        yield x.display


@pytest.fixture(scope="module")
def cal() -> Any:
    return small_calibration(64, 32, screen="magenta")


@pytest.fixture(scope="module")
def clip(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("clip") / "clip.mp4"
    make_test_video(str(path), 128, 64, seconds=4.0, rate=RATE, audio=True)
    return path


@pytest.fixture(scope="module")
def short_clip(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("clip") / "short.mp4"
    make_test_video(str(path), 64, 32, seconds=0.5, rate=RATE, audio=False)
    return path


@pytest.fixture(scope="module")
def cal_file(cal: Any, tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("cal") / "screen.vcb"
    cal.save(path)
    return path


# Window vs reference: pixel-channels more than one level apart allowed per 64x32 frame.
# Where the solved projector light is within ~1e-7 of 0, float rounding picks 0 or a tiny
# positive value and the inverse response is steepest there; a frame may have one or two.
OUTLIERS = 6


def level_diff(got: np.ndarray, want: np.ndarray) -> tuple[int, int]:
    """(max difference in levels, pixel-channels more than 1 level apart)."""
    d = np.abs(got.astype(int) - want.astype(int))
    return int(d.max()), int((d > 1).sum())


def _options(**kw: Any) -> Any:
    from viewcomp.rt.play.player import PlayerOptions

    base = dict(windowed=True, audio=False, stdin_fd=None, max_seconds=30.0)
    base.update(kw)
    return PlayerOptions(**base)


def _osc(address: str, *args: float) -> bytes:
    b = OscMessageBuilder(address)
    for a in args:
        b.add_arg(float(a), "f")
    return b.build().dgram


# ----------------------------------------------------------------------- playback
@pytest.mark.gl
def test_plays_in_order_with_audio_and_releases(display: str, cal: Any, clip: Path) -> None:
    from viewcomp.rt.play.player import Player

    audio_ok = open_alsa("null") is not None
    times: list[float] = []
    player = Player(cal, [clip], _options(audio=audio_ok, audio_device="null"),
                    on_frame=lambda p, f: times.append(f.time))  # fmt: skip
    stats = player.run()
    print("\n" + stats.summary())
    assert stats.presented + stats.dropped == 4 * RATE
    assert stats.presented >= 10  # timing is printed, not asserted
    assert all(b > a for a, b in itertools.pairwise(times))
    assert stats.files_played == 1
    assert player.renderer is not None and player.renderer.live_objects() == 0
    if audio_ok:
        assert stats.audio is not None
        assert stats.audio.written + stats.audio.dropped == pytest.approx(4.0, abs=0.25)


@pytest.mark.gl
def test_playlist_loop_and_stop(display: str, cal: Any, short_clip: Path, tmp_path: Path) -> None:
    from viewcomp.rt.play.player import Player

    folder = tmp_path / "kiosk"
    folder.mkdir()
    for name in ("b.mp4", "a.mp4"):
        (folder / name).write_bytes(short_clip.read_bytes())
    (folder / "notes.txt").write_text("not a video")
    seen: list[tuple[int, str]] = []

    def on_frame(player: Any, f: Any) -> None:
        if not seen or seen[-1] != (f.file_index, f.path.name):
            seen.append((f.file_index, f.path.name))
        if len(seen) == 3:
            player.stop()

    stats = Player(cal, [folder], _options(loop=True), on_frame=on_frame).run()
    assert seen == [(0, "a.mp4"), (1, "b.mp4"), (0, "a.mp4")]
    assert stats.files_played >= 3


# ----------------------------------------------------------------------- live input
@pytest.mark.gl
def test_osc_and_stdin_change_the_picture_within_two_frames(
    display: str, cal: Any, clip: Path
) -> None:
    from viewcomp.rt.play.player import Player

    r, w = os.pipe()
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    steps = [("osc", 45.0, 15), ("stdin", 130.0, None)]  # (source, angle, send at frame)
    state: dict[str, Any] = {"step": 0, "sent": None, "results": []}

    def check(player: Any, f: Any, eye: np.ndarray) -> tuple[int, int]:
        rec = f.record
        p = rec.params
        ref = compensate(p.model, yuv420p_to_rgb(f.planes), eye, p.alpha, p.beta)
        return level_diff(player.read_window(), ref)

    def on_frame(player: Any, f: Any) -> None:
        if state["step"] >= len(steps):
            player.stop()
            return
        source, angle, at = steps[state["step"]]
        target = cal.eye(angle=angle)
        if state["sent"] is None:
            if at is not None and f.index < at:
                return
            # this frame (already drawn, the old eye) is the "before" picture
            old = np.array(f.record.eye)
            before = check(player, f, old)
            ref_old = compensate(f.record.params.model, yuv420p_to_rgb(f.planes), old,
                                 f.record.params.alpha, f.record.params.beta)  # fmt: skip
            ref_new = compensate(f.record.params.model, yuv420p_to_rgb(f.planes), target,
                                 f.record.params.alpha, f.record.params.beta)  # fmt: skip
            changed = int(np.count_nonzero(np.abs(ref_old.astype(int) - ref_new) > 2))
            if source == "osc":
                tx.sendto(_osc("/viewcomp/angle", angle), player.osc_address)
            else:
                os.write(w, f"angle {angle:g}\n".encode())
            state["sent"] = (f.index, time.monotonic(), before, changed)
            return
        index, sent_at, before, changed = state["sent"]
        if np.allclose(f.record.eye, target, atol=1e-9):
            worst = check(player, f, f.record.eye)
            state["results"].append(dict(source=source, frames=f.index - index,
                                         ms=1e3 * (time.monotonic() - sent_at), before=before,
                                         after=worst, changed=changed))  # fmt: skip
            state["step"] += 1
            state["sent"] = None
        elif f.index - index > 2:
            state["results"].append(dict(source=source, frames=f.index - index, after=None))
            state["step"] += 1
            state["sent"] = None

    opts = _options(eye_tau=0.0, osc=("127.0.0.1", 0), stdin_fd=r, loop=True, angle=90.0)
    try:
        stats = Player(cal, [clip], opts, on_frame=on_frame).run()
    finally:
        tx.close()
        os.close(w)
        os.close(r)
    print()
    for res in state["results"]:
        print(f"{res['source']}: new angle drawn {res['frames']} frame(s) after sending",
              f"(~{res.get('ms', 0):.0f} ms to draw; window vs reference (max levels, "
              f"pixel-channels over 1): before {res.get('before')} after {res.get('after')}; "
              f"{res.get('changed')} "
              "pixels differ between the two angles)")  # fmt: skip
    print(f"latency receipt -> presented, last command: {stats.command_latency_ms_last:.0f} ms")
    assert [res["source"] for res in state["results"]] == ["osc", "stdin"]
    for res in state["results"]:
        assert res["after"] is not None, f"{res['source']}: no change within two frames"
        assert 1 <= res["frames"] <= 2
        assert res["before"][1] <= OUTLIERS and res["after"][1] <= OUTLIERS
        assert res["changed"] > 100  # the two angles' pictures really differ
    assert stats.inputs["osc"].applied == 1 and stats.inputs["stdin"].applied == 1


@pytest.mark.gl
def test_paper_method_follows_the_eye(display: str, cal: Any, clip: Path) -> None:
    """The paper method's model depends on the eye: it is re-uploaded when it changes, and
    every frame matches the reference with the FrameParams it used."""
    from viewcomp.rt.play.live import SetAngle
    from viewcomp.rt.play.player import Player

    target = cal.eye(angle=50.0)
    seen: dict[str, Any] = {"worst": (0, 0), "frames_to_model": None}

    def on_frame(player: Any, f: Any) -> None:
        rec = f.record
        p = rec.params
        ref = compensate(p.model, yuv420p_to_rgb(f.planes), rec.eye, p.alpha, p.beta)
        seen["worst"] = max(seen["worst"], level_diff(player.read_window(), ref))
        if f.index == 5:
            player.hub.put("test", SetAngle(50.0))
        elif f.index > 5 and np.allclose(rec.tone_eye, target, atol=1e-9):
            seen["frames_to_model"] = f.index - 5
            player.stop()

    opts = _options(method="paper", eye_tau=0.0, loop=True, max_seconds=20.0)
    Player(cal, [clip], opts, on_frame=on_frame).run()
    n, worst = seen["frames_to_model"], seen["worst"]
    print(f"\npaper method: the model for the new eye was in use {n} frame(s) after the "
          f"command; window vs reference: (max levels, pixel-channels over 1) {worst}")  # fmt: skip
    assert seen["frames_to_model"] is not None
    assert seen["worst"][1] <= OUTLIERS


@pytest.mark.gl
def test_keys_mouse_overlay_and_ab(display: str, cal: Any, clip: Path) -> None:
    """The glfw callbacks as glfw calls them (no real key presses under Xvfb)."""
    import glfw

    from viewcomp.rt.play.live import eye_to_polar
    from viewcomp.rt.play.player import Player

    log: dict[str, Any] = {}

    def on_frame(player: Any, f: Any) -> None:
        win = player._win
        angle = eye_to_polar(player.renderer.eye_state.target)[0]
        if f.index == 3:
            player._on_key(win, glfw.KEY_RIGHT, 0, glfw.PRESS, 0)  # 2 degrees to the right
            player._on_key(win, glfw.KEY_LEFT, 0, glfw.REPEAT, glfw.MOD_SHIFT)  # 10 left
        elif f.index == 5:
            log["keys"] = angle
            player._on_mouse_button(win, glfw.MOUSE_BUTTON_LEFT, glfw.PRESS, 0)
            x, y = glfw.get_cursor_pos(win)
            player._on_cursor(win, x + player._fb_size[0] / 4, y)  # a quarter: 45 degrees
            player._on_mouse_button(win, glfw.MOUSE_BUTTON_LEFT, glfw.RELEASE, 0)
        elif f.index == 7:
            log["mouse"] = angle
            player._on_key(win, glfw.KEY_C, 0, glfw.PRESS, 0)  # compensation off
        elif f.index == 8:
            log["identity"] = bool(f.record.identity)
            shot = player.read_window()
            log["passthrough"] = int(np.abs(shot.astype(int) - yuv420p_to_rgb(f.planes)).max())
            player._on_key(win, glfw.KEY_O, 0, glfw.PRESS, 0)  # overlay on
        elif f.index == 9:
            log["overlay"] = player._show_overlay
            player._on_key(win, glfw.KEY_Q, 0, glfw.PRESS, 0)

    stats = Player(cal, [clip], _options(eye_tau=0.0, angle=90.0), on_frame=on_frame).run()
    assert log["keys"] == pytest.approx(98.0)
    assert log["mouse"] == pytest.approx(98.0 - 45.0, abs=0.5)
    assert log["identity"] and log["overlay"]
    assert log["passthrough"] == 0  # C: the same pipeline with compensation off
    assert stats.presented == 10  # Q stopped it
    assert stats.inputs["key"].applied == 2 and stats.inputs["mouse"].applied == 1


@pytest.mark.gl
def test_fuzzed_inputs_while_playing(display: str, cal: Any, clip: Path) -> None:
    from tests.support.fuzzing import fuzz_player
    from viewcomp.rt.play.player import Player

    n = 10_000
    opts = dict(osc=("127.0.0.1", 0), loop=True, eye_tau=0.1, max_seconds=180)
    res = fuzz_player(lambda fd: Player(cal, [clip], _options(stdin_fd=fd, **opts)), n)
    assert res.sender_returncode == 0, res.sender_stderr
    want, stats = res.want, res.stats
    got = stats.inputs
    print(f"\nsent {n} items in {res.sender_seconds:.1f} s; expected "
          f"{want}; got " + ", ".join(f"{k}: applied {v.applied} rejected {v.rejected}"
                                      for k, v in got.items())
          + f"; settled {res.settle_s} s after the sender ended; "
          f"{stats.summary()}; longest main-loop gap {stats.max_loop_gap_ms:.0f} ms")  # fmt: skip
    for src, (valid, invalid) in want.items():
        assert got[src].applied == valid, src
        assert got[src].received == valid, src
        assert got[src].rejected == invalid, src
    assert stats.presented > 30


# ----------------------------------------------------------------------- command line
def _cli(*args: str, **kw: Any) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, "-m", "viewcomp", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, **kw)  # fmt: skip


def test_cli_unreadable_video_is_a_clear_error(cal_file: Path, tmp_path: Path) -> None:
    bad = tmp_path / "bad.mp4"
    bad.write_bytes(b"not a video at all")
    _, err = _cli("play", str(cal_file), str(bad), "--windowed").communicate(timeout=60)
    assert "cannot read video" in err and "fix:" in err
    assert "Traceback" not in err


@pytest.mark.gl
def test_cli_monitors(display: str, cal_file: Path, clip: Path) -> None:
    p = _cli("play", "--list-monitors")
    out, err = p.communicate(timeout=60)
    assert p.returncode == 0 and out.startswith("0: ") and "1280x720" in out
    p = _cli("play", str(cal_file), str(clip), "--monitor", "7", "--no-audio")
    out, err = p.communicate(timeout=60)
    assert p.returncode == 2
    assert "no monitor 7" in err and "0: " in err and "Traceback" not in err


@pytest.mark.gl
def test_cli_sigterm_exits_cleanly(display: str, cal_file: Path, clip: Path) -> None:
    p = _cli("play", str(cal_file), str(clip), "--loop", "--no-audio", "--overlay",
             stdin=subprocess.DEVNULL)  # fmt: skip
    try:
        assert p.stderr is not None
        lines = []
        while not any("window" in ln for ln in lines) and len(lines) < 50:
            line = p.stderr.readline()  # "viewcomp play: window ..." once the window is up
            if not line:
                break
            lines.append(line)
        assert any("window" in ln for ln in lines), lines
        time.sleep(1.5)
        p.send_signal(signal.SIGTERM)
        out, err = p.communicate(timeout=30)
    finally:
        if p.poll() is None:
            p.kill()
    assert p.returncode == 0, err
    assert "frames presented" in out


@pytest.mark.gl
def test_embed_example_checks_against_reference(display: str) -> None:
    p = subprocess.run([sys.executable, str(ROOT / "examples" / "embed_host.py"), "--frames",
                        "20", "--check", "--size", "320x240"], capture_output=True, text=True,
                       timeout=120)  # fmt: skip
    print(p.stdout)
    assert p.returncode == 0, p.stderr
    assert "window vs numpy reference" in p.stdout


# ----------------------------------------------------------------------- measurement
@pytest.mark.gl
@pytest.mark.slow
def test_measure_720p_at_1280x720(display: str, tmp_path: Path) -> None:
    """A 720p 30 fps clip, fullscreen 1280x720 on Xvfb, a 640x320 calibration: printed."""
    from viewcomp.rt.play.player import Player

    video = tmp_path / "clip720.mp4"
    make_test_video(str(video), 1280, 720, seconds=10.0, rate=RATE, audio=True)
    cal640 = small_calibration(640, 320, screen="magenta")
    load0 = os.getloadavg()
    stats = Player(cal640, [video], _options(windowed=False, audio=True, max_seconds=None)).run()
    print(f"\n720p 30 fps -> 640x320 grid -> 1280x720 Xvfb: {stats.summary()}; load average "
          f"before {load0[0]:.2f}, after {os.getloadavg()[0]:.2f} (2 cores)")  # fmt: skip
    assert stats.presented + stats.dropped == 10 * RATE


@pytest.mark.gl
def test_systemd_hears_ready_after_the_first_frame_and_watchdog_pings(
    display: str, cal: Any, short_clip: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Under a unit of Type=notify (NOTIFY_SOCKET, WATCHDOG_USEC set) the player says READY=1
    once its first frame is presented, not before; pings the watchdog from its loop; and
    says STOPPING=1 when it ends."""
    from viewcomp.rt.play.player import Player

    path = str(tmp_path / "notify")
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    sock.bind(path)
    sock.setblocking(False)
    monkeypatch.setenv("NOTIFY_SOCKET", path)
    monkeypatch.setenv("WATCHDOG_USEC", "200000")  # pings every 0.1 s
    monkeypatch.delenv("WATCHDOG_PID", raising=False)
    heard: list[tuple[int, bytes]] = []

    def drain(presented: int) -> None:
        while True:
            try:
                heard.append((presented, sock.recv(4096)))
            except BlockingIOError:
                return

    def on_frame(player: Any, f: Any) -> None:
        drain(f.index)  # called before the frame is swapped onto the screen

    with sock:
        stats = Player(cal, [short_clip], _options(max_seconds=3.0), on_frame=on_frame).run()
        drain(stats.presented)
    ready = [i for i, m in heard if m.startswith(b"READY=1")]
    assert len(ready) == 1 and ready[0] >= 1, heard[:5]  # after the first swap, once
    assert any(m == b"WATCHDOG=1" for _, m in heard)
    assert heard[-1][1] == b"STOPPING=1"


@pytest.mark.gl
def test_a_deleted_playlist_file_is_skipped_with_one_log_line(
    display: str, cal: Any, short_clip: Path, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """A looping kiosk whose second file is deleted while it plays: the player goes on with
    the others and says so once (not once per loop); put back, the file plays again and the
    player says that too."""
    import logging
    import shutil

    from viewcomp.rt.play.player import Player

    a, b = tmp_path / "a.mp4", tmp_path / "b.mp4"
    shutil.copyfile(short_clip, a)
    shutil.copyfile(short_clip, b)
    state = {"deleted_at": None, "restored": False}

    def on_frame(player: Any, f: Any) -> None:
        if state["deleted_at"] is None and f.index >= 3:
            b.unlink()  # deleted while the first file plays
            state["deleted_at"] = f.index
        elif not state["restored"] and f.index >= 60:  # several loops later
            shutil.copyfile(short_clip, b)
            state["restored"] = True

    with caplog.at_level(logging.INFO, logger="viewcomp.rt.play"):
        stats = Player(cal, [a, b], _options(loop=True, max_seconds=8.0), on_frame=on_frame).run()
    msgs = [r.getMessage() for r in caplog.records]
    skipped = [m for m in msgs if m.startswith("skipping") and "b.mp4" in m]
    print(f"\n{stats.presented} frames; log: {[m[:70] for m in msgs if 'b.mp4' in m]}")
    assert state["restored"], "the clip did not loop long enough to test the return"
    assert len(skipped) == 1, msgs
    assert any("b.mp4 can be read again" in m for m in msgs), msgs
