"""`viewcomp play` as a kiosk meets it: the projector's display switched off and on, a playlist
file replaced while it plays. Under a private Xvfb whose output is really switched off and on
through RandR (tests/support/randr.py), so glfw sees the same notifications as with a real
projector. Without Xvfb they skip, except under VIEWCOMP_REQUIRE_GL=1, where they fail.
"""

from __future__ import annotations

import logging
import os
import shutil
import threading
import time
from pathlib import Path
from typing import Any

import pytest

from tests.support.calibrations import small_calibration
from tests.support.randr import DisplayOutput
from tests.support.synthetic import make_test_video
from viewcomp.rt.play.xvfb import Xvfb, xvfb_available

pytestmark = pytest.mark.usefixtures("session_gl_current")

RATE = 30


@pytest.fixture(scope="module")
def display() -> Any:
    if not xvfb_available():
        if os.environ.get("VIEWCOMP_REQUIRE_GL") == "1":
            pytest.fail("Xvfb is not installed (VIEWCOMP_REQUIRE_GL=1)", pytrace=False)
        pytest.skip("Xvfb is not installed (Debian package xvfb)")
    with Xvfb((640, 360)) as x:
        yield x.display


@pytest.fixture(scope="module")
def cal() -> Any:
    return small_calibration(64, 32, screen="magenta")


def _clip(folder: Path, name: str, seconds: float, w: int = 64, h: int = 32) -> Path:
    path = folder / name
    make_test_video(str(path), w, h, seconds=seconds, rate=RATE, audio=False)
    return path


def _options(**kw: Any) -> Any:
    from viewcomp.rt.play.player import PlayerOptions

    base = dict(audio=False, stdin_fd=None, max_seconds=30.0, loop=True)
    base.update(kw)
    return PlayerOptions(**base)


@pytest.mark.gl
def test_the_display_switched_off_and_on_is_played_through(
    display: str, cal: Any, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """Fullscreen on the Xvfb's one output; the output switched off for 1.5 s, then on: the
    player does not stop, counts the frames due meanwhile as not shown, says each event once,
    and goes fullscreen on the monitor again, drawing at the monitor's size."""
    import glfw

    from viewcomp.rt.play.commands import SetAngle
    from viewcomp.rt.play.player import Player

    clip = _clip(tmp_path, "a.mp4", 1.0)
    state: dict[str, Any] = {"off": None, "on": None, "after": [], "during": 0, "pending": 0}
    out = DisplayOutput(display)
    holder: dict[str, Any] = {}

    def switch() -> None:
        time.sleep(1.0)
        out.off()
        state["off"] = time.monotonic()
        for i in range(300):  # live input goes on while nothing is shown
            holder["player"].hub.put("test", SetAngle(60.0 + i % 60))
            time.sleep(0.004)
        state["pending"] = len(holder["player"]._pending_inputs)
        time.sleep(0.3)
        out.on()
        state["on"] = time.monotonic()

    def on_frame(player: Any, f: Any) -> None:
        if state["on"] is not None:
            state["after"].append(
                (glfw.get_window_monitor(player._win) is not None, player._fb_size)
            )
            if len(state["after"]) >= 30:
                player.stop()
        elif state["off"] is not None and time.monotonic() > state["off"] + 0.3:
            state["during"] += 1  # drawn while the display was gone

    t = threading.Thread(target=switch, daemon=True)
    with out, caplog.at_level(logging.INFO, logger="viewcomp.rt.play"):
        holder["player"] = Player(cal, [clip], _options(max_seconds=15.0), on_frame=on_frame)
        t.start()
        stats = holder["player"].run()
        t.join()
    msgs = [r.getMessage() for r in caplog.records]
    print(f"\n{stats.summary()}")
    assert stats.display_losses == 1, msgs
    assert sum(m.startswith("display lost") for m in msgs) == 1, msgs
    assert sum(m.startswith("display back") for m in msgs) == 1, msgs
    assert state["during"] == 0  # nothing drawn into a window with no monitor
    assert state["pending"] <= 2  # inputs applied unshown are not kept one by one
    assert stats.inputs["test"].applied == 300
    due = RATE * (state["on"] - state["off"])  # frames of the clip due while it was off
    assert 0.5 * due <= stats.unshown <= due + 5, (stats.unshown, due)  # late ones drop
    assert len(state["after"]) >= 30, "playback did not resume after the display came back"
    assert all(full and size == (640, 360) for full, size in state["after"]), state["after"]


@pytest.mark.gl
@pytest.mark.parametrize("how", ["renamed", "rewritten"])
def test_a_playlist_file_replaced_while_playing_plays_its_new_content(
    display: str, cal: Any, tmp_path: Path, how: str, caplog: pytest.LogCaptureFixture
) -> None:
    """A looping kiosk's file replaced while it plays - by a rename over it (what an atomic
    upload does) or rewritten in place (a plain copy over it): no crash, the new content (a
    longer clip) plays from the next loop on."""
    from viewcomp.rt.play.player import Player

    a = _clip(tmp_path, "a.mp4", 0.5)
    b = _clip(tmp_path, "b.mp4", 0.5)
    new = _clip(tmp_path / "..", f"new-{how}.mp4", 1.5)
    state: dict[str, Any] = {"replaced": False, "b_times": []}

    def on_frame(player: Any, f: Any) -> None:
        if f.path == b:
            state["b_times"].append((state["replaced"], f.time))
            if not state["replaced"] and f.time > 0.2:  # while b itself plays
                if how == "renamed":
                    tmp = b.with_suffix(".part")
                    shutil.copyfile(new, tmp)
                    os.replace(tmp, b)
                else:
                    shutil.copyfile(new, b)
                state["replaced"] = True

    with caplog.at_level(logging.INFO, logger="viewcomp.rt.play"):
        opts = _options(windowed=True, max_seconds=6.0)
        stats = Player(cal, [a, b], opts, on_frame=on_frame).run()
    print(f"\n{how}: {stats.summary()}")
    assert state["replaced"]
    later = [t for replaced, t in state["b_times"] if replaced]
    assert max(later) > 1.0, later[-5:]  # the 1.5 s clip: the new content played
