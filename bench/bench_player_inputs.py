"""Benchmark of the player under fuzzed live input: prints one JSON object to stdout.

A windowed player (a private Xvfb, a 64x32 simulated calibration, a 4-second 30 frames/s
clip, looping) receives 10,000 items, half OSC datagrams and half stdin lines, about 60 %
malformed, from another process (:mod:`tests.support.fuzzing`). Per round it prints the
longest gap between main-loop iterations (the figure a kiosk cares about: a stall shows as a
frozen picture), how long after the sender ended every valid item had been applied, and the
frames presented and dropped. On a shared machine these vary with whoever else runs: compare
rounds of one run, never against a fixed number. Run from the repository root::

    .venv/bin/python bench/bench_player_inputs.py [--rounds 3] [--items 10000]
"""

from __future__ import annotations

import sys
from pathlib import Path

# The repository on sys.path: the synthetic models and calibrations are tests.support's.
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import argparse
import datetime
import json
import tempfile

from tests.support.calibrations import small_calibration
from tests.support.fuzzing import fuzz_player
from tests.support.synthetic import make_test_video
from viewcomp.rt.play.player import Player, PlayerOptions
from viewcomp.rt.play.xvfb import Xvfb, xvfb_available


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=3, help="fuzzed playbacks (default 3)")
    ap.add_argument("--items", type=int, default=10_000, help="items sent per round")
    args = ap.parse_args(argv)
    if not xvfb_available():
        print("bench_player_inputs: Xvfb is not installed (Debian package xvfb)", file=sys.stderr)
        return 2
    cal = small_calibration(64, 32, screen="magenta")
    rounds = []
    with tempfile.TemporaryDirectory() as tmp, Xvfb((1280, 720)):
        clip = Path(tmp) / "clip.mp4"
        make_test_video(str(clip), 128, 64, seconds=4.0, rate=30, audio=False)
        for _ in range(args.rounds):

            def make(fd: int) -> Player:
                opts = PlayerOptions(
                    windowed=True,
                    audio=False,
                    stdin_fd=fd,
                    osc=("127.0.0.1", 0),
                    loop=True,
                    eye_tau=0.1,
                    max_seconds=180.0,
                )
                return Player(cal, [clip], opts)

            res = fuzz_player(make, args.items)
            s = res.stats
            rounds.append(
                {
                    "max_loop_gap_ms": round(s.max_loop_gap_ms, 1),
                    "settle_s": None if res.settle_s is None else round(res.settle_s, 2),
                    "sender_s": round(res.sender_seconds, 2),
                    "presented": s.presented,
                    "dropped": s.dropped,
                    "all_valid_applied": all(
                        s.inputs[k].applied == v[0] for k, v in res.want.items()
                    ),
                }
            )
    report = {
        "when": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "items_per_round": args.items,
        "rounds": rounds,
    }
    print(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
