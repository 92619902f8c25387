"""Fuzzed live input for a running player: valid and malformed OSC and stdin lines.

The sender runs in its own process (so the player's process sees real sockets and a real
pipe) and reports how many valid and invalid items it sent per source; :func:`fuzz_player`
drives a :class:`viewcomp.rt.play.player.Player` with it and returns what happened. Used by
the test (every valid item applied, every malformed one counted) and by
``bench/bench_player_inputs.py`` (the longest main-loop gap while fuzzed, printed).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
import time
from dataclasses import dataclass
from typing import Any

SENDER = r"""
import json, math, os, random, socket, sys, time
from pythonosc.osc_message_builder import OscMessageBuilder
from pythonosc.osc_bundle_builder import OscBundleBuilder, IMMEDIATELY
host, port, fd, n = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
rng = random.Random(1234)
def msg(addr, args, types):
    b = OscMessageBuilder(addr)
    for a, t in zip(args, types):
        b.add_arg(a, t)
    return b.build()
def valid_osc():
    k = rng.randrange(5)
    if k == 0: return msg("/viewcomp/angle", [rng.uniform(1, 179)], "f").dgram, 1, 0
    if k == 1: return msg("/viewcomp/angle", [rng.randint(1, 179)], "i").dgram, 1, 0
    if k == 2: return msg("/viewcomp/angle", [rng.uniform(1, 179)], "d").dgram, 1, 0
    if k == 3:
        e = [rng.uniform(-1, 1), rng.uniform(-.5, .5), rng.uniform(.1, 2)]
        return msg("/viewcomp/eye", e, "fff").dgram, 1, 0
    b = OscBundleBuilder(IMMEDIATELY)
    b.add_content(msg("/viewcomp/angle", [rng.uniform(1, 179)], "f"))
    b.add_content(msg("/viewcomp/angle", [500.0], "f"))
    return b.build().dgram, 1, 1
def invalid_osc():
    k = rng.randrange(8)
    if k == 0: return b"\x01" + os.urandom(rng.randrange(0, 200)), 0, 1
    if k == 1:
        a = rng.choice([0.0, 180.0, -5.0, 1e9, math.nan, math.inf])
        return msg("/viewcomp/angle", [a], "f").dgram, 0, 1
    if k == 2: return msg("/viewcomp/eye", [0.1, 0.2], "ff").dgram, 0, 1
    if k == 3: return msg("/viewcomp/eye", [0.1, 0.2, -0.5], "fff").dgram, 0, 1
    if k == 4: return msg("/viewcomp/angle", ["sixty"], "s").dgram, 0, 1
    if k == 5: return msg("/viewcomp/tilt", [1.0], "f").dgram, 0, 1
    if k == 6:
        d = msg("/viewcomp/angle", [60.0], "f").dgram
        return d[: len(d) - rng.randrange(1, 4)], 0, 1
    return b"", 0, 1
def valid_line():
    k = rng.randrange(3)
    if k == 0: return f"angle {rng.uniform(1, 179):.3f}\n".encode(), 1, 0
    if k == 1:
        x, y, z = rng.uniform(-1, 1), rng.uniform(-.5, .5), rng.uniform(.1, 2)
        return f"EYE {x:.3f},{y:.3f},{z:.3f}\n".encode(), 1, 0
    return f"  angle\t{rng.randint(1, 179)}  \n".encode(), 1, 0
def invalid_line():
    k = rng.randrange(7)
    if k == 0:
        junk = "".join(chr(rng.randrange(32, 127)) for _ in range(rng.randrange(0, 60)))
        return ("?" + junk + "\n").encode(), 0, 1
    if k == 1:
        a = rng.choice(["0", "180", "-1", "nan", "inf", "1e400", "x"])
        return f"angle {a}\n".encode(), 0, 1
    if k == 2: return b"eye 1 2\n", 0, 1
    if k == 3: return b"eye 0 0 -1\n", 0, 1
    if k == 4: return b"a" * 1000 + b"\n", 0, 1
    if k == 5: return b"\xff\xfe\xfd angle 60\n", 0, 1
    return b"angle 10 20\n", 0, 1
tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
count = {"osc": [0, 0], "stdin": [0, 0]}
t0 = time.monotonic()
for i in range(n):
    if i % 2 == 0:
        data, v, bad = (valid_osc if rng.random() < 0.4 else invalid_osc)()
        tx.sendto(data, (host, port))
        src = "osc"
    else:
        if rng.random() < 0.05:
            os.write(fd, rng.choice([b"\n", b"# comment\n", b"   \n"]))
        data, v, bad = (valid_line if rng.random() < 0.4 else invalid_line)()
        os.write(fd, data)
        src = "stdin"
    count[src][0] += v
    count[src][1] += bad
    if i % 20 == 19:
        time.sleep(0.004)
print(json.dumps({"count": count, "seconds": time.monotonic() - t0}))
"""


@dataclass
class FuzzResult:
    """What the sender sent (``want``: source -> [valid, invalid]), its run, and the player's
    statistics after playback (``stats``); ``settle_s`` is how long after the sender ended
    the player had applied every valid item (None: not within ``settle_limit_s``)."""

    want: dict[str, list[int]]
    sender_seconds: float
    sender_returncode: int
    sender_stderr: str
    settle_s: float | None
    stats: Any


def fuzz_player(
    make_player: Any, n: int = 10_000, settle_limit_s: float = 60.0, tail_s: float = 0.3
) -> FuzzResult:
    """Play with ``make_player(stdin_fd)`` (a Player listening for OSC) while ``n`` items are
    sent to it, half OSC, half stdin; stop once every valid item is applied (or after
    ``settle_limit_s``) plus ``tail_s`` more seconds of frames."""
    r, w = os.pipe()
    result: dict[str, Any] = {}
    player = make_player(r)

    def drive() -> None:
        while player.osc_address is None:
            time.sleep(0.01)
        host, port = player.osc_address
        proc = subprocess.run(
            [sys.executable, "-c", SENDER, host, str(port), str(w), str(n)],
            pass_fds=(w,),
            capture_output=True,
            text=True,
            timeout=600,
        )
        result["sender"] = proc
        if proc.returncode == 0:
            want = json.loads(proc.stdout)["count"]
            result["want"] = want
            start = time.monotonic()
            while time.monotonic() - start < settle_limit_s:
                got = player.hub.snapshot()
                if all(
                    src in got
                    and got[src].applied == want[src][0]
                    and got[src].rejected == want[src][1]
                    for src in want
                ):
                    result["settle_s"] = time.monotonic() - start
                    break
                time.sleep(0.02)
        time.sleep(tail_s)
        player.stop()

    driver = threading.Thread(target=drive, daemon=True)
    driver.start()
    try:
        stats = player.run()
    finally:
        driver.join(timeout=settle_limit_s + 60)
        os.close(w)
        os.close(r)
    proc = result.get("sender")
    return FuzzResult(
        want=result.get("want", {}),
        sender_seconds=json.loads(proc.stdout)["seconds"] if proc and proc.returncode == 0 else 0,
        sender_returncode=proc.returncode if proc else -1,
        sender_stderr=proc.stderr if proc else "the sender did not run",
        settle_s=result.get("settle_s"),
        stats=stats,
    )
