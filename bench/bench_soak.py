"""Soak benchmark: `viewcomp play` run as a kiosk runs it, watched from outside; prints a table.

One ``viewcomp play`` process, fullscreen on a private Xvfb, plays a looping playlist folder
(two clips and two stills) through a simulated calibration while it is pushed as a kiosk is:

- an OSC flood (``/viewcomp/angle`` at ``--osc-rate`` datagrams/s from another thread),
- stdin commands every half second (angles, eyes, normalised angles, a status request),
- a face tracker feeding eyes (``--track-camera``: a walk of a face in front of the screen,
  rendered by :mod:`viewcomp.rt.track.simwalk`, as long as the soak, paced at 10 frames/s),
- at 25 % of the run one playlist file deleted, at 40 % another replaced (renamed over) by a
  different clip, at 50 % the deleted one put back,
- at 60 % the projector's display switched off for 30 s and on again (the Xvfb output
  disabled and re-enabled through RandR, as a projector or a pulled cable looks to X).

Every ``--sample`` seconds it reads the process's resident memory, open file descriptors and
threads from ``/proc`` and the dropped frames from its ``status`` line, and prints them. At
the end it prints what the issue asks to see - memory within 5 % of its level after the first
minute, no growth in descriptors or threads (the median of the last fifth of the samples
against that of the first fifth after the first minute), no crash, each playlist and display
event said once in the log - and writes the whole series as JSON with ``--json``. Figures
depend on the machine and whoever else runs on it: read them as a series, not a limit. Run
from the repository root::

    .venv/bin/python bench/bench_soak.py [--minutes 30] [--sample 10] [--json soak.json]
"""

from __future__ import annotations

import sys
from pathlib import Path

# The repository on sys.path: the simulated calibration and the RandR switch are tests.support's.
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import argparse
import datetime
import itertools
import json
import os
import random
import re
import shutil
import signal
import socket
import statistics
import subprocess
import tempfile
import threading
import time
from dataclasses import replace
from typing import IO, Any

import av
import cv2
import numpy as np
from pythonosc.osc_message_builder import OscMessageBuilder

from tests.support.calibrations import small_calibration
from tests.support.randr import DisplayOutput
from tests.support.synthetic import make_test_video
from viewcomp.calib.world.rig import Device
from viewcomp.rt.play.xvfb import Xvfb, xvfb_available
from viewcomp.rt.track.simwalk import render_walk, walk, walk_camera

TRACK_FPS = 10
TRACK_SIZE = (640, 360)


def _tracking_camera() -> Device:
    """The walk's webcam at 640x360 (the same pose and field of view)."""
    return replace(walk_camera(), resolution=TRACK_SIZE)


def _write_track_video(path: Path, seconds: float) -> None:
    """A face walking in front of the screen for ``seconds`` (a 20 s walk, back and forth)."""
    _, eyes = walk(seconds=20.0, fps=TRACK_FPS)
    frames = render_walk(_tracking_camera(), eyes)
    cycle = frames + frames[::-1]
    n = int(seconds * TRACK_FPS)
    with av.open(str(path), "w") as out:
        stream = out.add_stream("libx264", rate=TRACK_FPS)
        stream.width, stream.height = TRACK_SIZE
        stream.pix_fmt = "yuv420p"
        stream.options = {"preset": "ultrafast"}
        for i in range(n):
            rgb = cv2.cvtColor(cycle[i % len(cycle)], cv2.COLOR_BGR2RGB)
            out.mux(stream.encode(av.VideoFrame.from_ndarray(rgb, format="rgb24")))
        out.mux(stream.encode(None))


def _playlist(folder: Path, grid: tuple[int, int]) -> None:
    folder.mkdir()
    w, h = grid
    make_test_video(str(folder / "01-clip.mp4"), w, h, seconds=6.0, rate=30, audio=False)
    rng = np.random.default_rng(0)
    still = (rng.random((h, w, 3)) * 255).astype(np.uint8)
    cv2.imwrite(str(folder / "02-still.png"), cv2.GaussianBlur(still, (0, 0), 8))
    make_test_video(str(folder / "03-clip.mp4"), w, h, seconds=4.0, rate=25, audio=False)
    cv2.imwrite(str(folder / "04-still.jpg"), 255 - cv2.GaussianBlur(still, (0, 0), 4))


def _proc(pid: int) -> dict[str, float]:
    """Resident memory (MiB), open descriptors and threads of process ``pid``."""
    rss = 0.0
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                rss = int(line.split()[1]) / 1024.0
    return {
        "rss_mib": rss,
        "fds": len(os.listdir(f"/proc/{pid}/fd")),
        "threads": len(os.listdir(f"/proc/{pid}/task")),
    }


def _read_lines(stream: IO[str], into: list[tuple[float, str]]) -> None:
    for line in stream:
        into.append((time.monotonic(), line.rstrip("\n")))


def _osc_flood(port: int, rate: float, stop: threading.Event, sent: list[int]) -> None:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rnd = random.Random(1)
    period = 1.0 / rate
    next_t = time.monotonic()
    while not stop.is_set():
        b = OscMessageBuilder("/viewcomp/angle")
        b.add_arg(rnd.uniform(40.0, 140.0), "f")
        sock.sendto(b.build().dgram, ("127.0.0.1", port))
        sent[0] += 1
        next_t += period
        time.sleep(max(0.0, next_t - time.monotonic()))
    sock.close()


def _stdin_commands(pipe: IO[str], stop: threading.Event, sent: list[int]) -> None:
    rnd = random.Random(2)
    lines = ["angle {a:.1f}", "eye {x:.3f} 0.1 {z:.3f}", "norm {n:.2f}", "status"]
    while not stop.wait(0.5):
        text = rnd.choice(lines).format(
            a=rnd.uniform(40, 140), x=rnd.uniform(-1, 1), z=rnd.uniform(1, 3), n=rnd.random()
        )
        try:
            pipe.write(text + "\n")
            pipe.flush()
        except (BrokenPipeError, ValueError):
            return
        sent[0] += 1


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _dropped(out: list[tuple[float, str]]) -> int | None:
    for _, line in reversed(out):
        if line.startswith("status "):
            for field in line.split():
                if field.startswith("dropped="):
                    return int(field.partition("=")[2])
    return None


def _growth(series: list[float]) -> tuple[float, float]:
    """(median of the first fifth, median of the last fifth) of ``series``."""
    k = max(1, len(series) // 5)
    return statistics.median(series[:k]), statistics.median(series[-k:])


class _Events:
    """The playlist and display events of the run, each done once at its share of it."""

    def __init__(self, folder: Path, spare: Path, output: DisplayOutput, seconds: float) -> None:
        self.folder, self.spare, self.output = folder, spare, output
        self.deleted = folder / "03-clip.mp4"
        self.kept = spare.parent / "kept-03-clip.mp4"
        self.plan = [
            (0.25 * seconds, "delete 03-clip.mp4", self._delete),
            (0.40 * seconds, "replace 01-clip.mp4", self._replace),
            (0.50 * seconds, "restore 03-clip.mp4", self._restore),
            (0.60 * seconds, "display off", output.off),
            (0.60 * seconds + 30.0, "display on", output.on),
        ]
        self.done: list[tuple[float, str]] = []

    def _delete(self) -> None:
        shutil.copyfile(self.deleted, self.kept)
        self.deleted.unlink()

    def _replace(self) -> None:
        tmp = self.folder / ".01-clip.part"
        shutil.copyfile(self.spare, tmp)
        os.replace(tmp, self.folder / "01-clip.mp4")

    def _restore(self) -> None:
        shutil.copyfile(self.kept, self.deleted)

    def due(self, elapsed: float) -> None:
        while self.plan and self.plan[0][0] <= elapsed:
            _, name, act = self.plan.pop(0)
            act()
            self.done.append((elapsed, name))
            print(f"# {elapsed:7.1f} s  {name}", flush=True)


def _start_player(tmp: Path, cal_path: Path, port: int) -> subprocess.Popen[str]:
    exe = Path(sys.executable).parent / "viewcomp"
    cmd = [
        str(exe), "play", str(cal_path), str(tmp / "playlist"), "--loop", "--monitor", "0",
        "--no-audio", "--osc", f"127.0.0.1:{port}", "--track-camera", str(tmp / "track.mp4"),
        "--still-seconds", "3",
    ]  # fmt: skip
    return subprocess.Popen(
        cmd,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        bufsize=1,
    )


def _soak(args: argparse.Namespace, tmp: Path, display: str) -> dict[str, Any]:
    seconds = 60.0 * args.minutes
    grid = (256, 128)
    cal = small_calibration(*grid, screen="magenta")
    cal = replace(cal, rig=replace(cal.rig, tracker=_tracking_camera()))
    cal.save(tmp / "cal.vcb")
    _playlist(tmp / "playlist", grid)
    make_test_video(str(tmp / "spare.mp4"), *grid, seconds=5.0, rate=24, audio=False)
    print(f"# writing the tracker's walk ({seconds + 60:.0f} s at {TRACK_FPS} fps)", flush=True)
    _write_track_video(tmp / "track.mp4", seconds + 60.0)
    port = _free_port()
    stop = threading.Event()
    osc_sent, stdin_sent = [0], [0]
    out: list[tuple[float, str]] = []
    err: list[tuple[float, str]] = []
    samples: list[dict[str, Any]] = []
    with DisplayOutput(display) as output:
        events = _Events(tmp / "playlist", tmp / "spare.mp4", output, seconds)
        proc = _start_player(tmp, tmp / "cal.vcb", port)
        assert proc.stdout is not None and proc.stderr is not None and proc.stdin is not None
        readers = [
            threading.Thread(target=_read_lines, args=(proc.stdout, out), daemon=True),
            threading.Thread(target=_read_lines, args=(proc.stderr, err), daemon=True),
        ]
        for t in readers:
            t.start()
        t0 = time.monotonic()
        pushers = [
            threading.Thread(target=_osc_flood, args=(port, args.osc_rate, stop, osc_sent)),
            threading.Thread(target=_stdin_commands, args=(proc.stdin, stop, stdin_sent)),
        ]
        for t in pushers:
            t.start()
        print("#  time s   RSS MiB   fds  threads  dropped  osc sent  stdin sent", flush=True)
        try:
            while (elapsed := time.monotonic() - t0) < seconds and proc.poll() is None:
                events.due(elapsed)
                s = {"t": elapsed, **_proc(proc.pid), "dropped": _dropped(out)}
                samples.append(s)
                print(
                    f"{elapsed:8.1f} {s['rss_mib']:9.1f} {s['fds']:5d} {s['threads']:8d} "
                    f"{s['dropped'] if s['dropped'] is not None else '-':>8} "
                    f"{osc_sent[0]:9d} {stdin_sent[0]:11d}",
                    flush=True,
                )
                time.sleep(min(args.sample, max(0.0, seconds - elapsed)))
            crashed = proc.poll()
        finally:
            stop.set()
            for t in pushers:
                t.join()
            if proc.poll() is None:
                proc.send_signal(signal.SIGTERM)
            code = proc.wait(timeout=60)
            for t in readers:
                t.join(timeout=5)
    return {
        "seconds": seconds,
        "samples": samples,
        "events": events.done,
        "exit": code,
        "crashed": crashed,
        "log": [line for _, line in err],
        "summary": [line for _, line in out if not line.startswith("status ")][-3:],
        "osc_sent": osc_sent[0],
        "stdin_sent": stdin_sent[0],
    }


def _verdict(run: dict[str, Any], settle: float) -> list[tuple[str, bool, str]]:
    """What the run shows, line by line: (what, held, the figures)."""
    later = [s for s in run["samples"] if s["t"] >= settle]
    checks: list[tuple[str, bool, str]] = []
    if len(later) >= 2:
        base = later[0]["rss_mib"]
        worst = max(abs(s["rss_mib"] - base) for s in later) / base
        checks.append(
            (
                f"memory within 5 % of its level at {settle:.0f} s",
                worst <= 0.05,
                f"{base:.1f} MiB then, worst {100 * worst:.1f} % off, "
                f"{later[-1]['rss_mib']:.1f} MiB at the end",
            )
        )
        for key in ("fds", "threads"):
            first, last = _growth([float(s[key]) for s in later])
            span = f"{min(s[key] for s in later)}-{max(s[key] for s in later)}"
            checks.append(
                (
                    f"no growth in {key}",
                    last <= first,
                    f"median {first:.0f} early, {last:.0f} late (range {span})",
                )
            )
    else:
        checks.append(("enough samples after the first minute", False, f"{len(later)}"))
    alive = run["crashed"] is None and run["exit"] == 0
    checks.append(("no crash", alive, f"running to the end: {run['crashed'] is None}, "
                   f"exit status after SIGTERM {run['exit']}"))  # fmt: skip
    log = run["log"]
    said = {
        "03-clip.mp4 deleted: said once": sum("gone" in m and "03-clip.mp4" in m for m in log),
        "03-clip.mp4 put back: said once": sum("new file" in m and "03-clip.mp4" in m for m in log),
        "display lost: said once": sum("display lost" in m for m in log),
        "display back: said once": sum("display back" in m for m in log),
    }
    for what, n in said.items():
        checks.append((what, n == 1, f"{n} log line{'s' if n != 1 else ''}"))
    summary = " ".join(run["summary"])
    for source in ("osc", "stdin", "track"):
        found = re.search(rf"; {source}: (\d+) applied", summary)
        n = int(found.group(1)) if found else 0
        checks.append((f"{source} input applied", n > 0, f"{n} commands"))
    tracebacks = sum("Traceback" in m for m in log)
    checks.append(("no traceback in the log", tracebacks == 0, f"{tracebacks}"))
    return checks


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--minutes", type=float, default=30.0, help="length (default 30)")
    ap.add_argument("--sample", type=float, default=10.0, help="seconds between samples")
    ap.add_argument("--settle", type=float, default=60.0, help="seconds before the baseline")
    ap.add_argument("--osc-rate", type=float, default=200.0, help="OSC datagrams per second")
    ap.add_argument("--json", type=Path, help="write the run (series, events, log) here")
    args = ap.parse_args(argv)
    if not xvfb_available():
        print("bench_soak: Xvfb is not installed (Debian package xvfb)", file=sys.stderr)
        return 2
    if 60.0 * args.minutes < args.settle + 60.0:
        print("bench_soak: --minutes must leave a minute after --settle", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory() as tmp, Xvfb((640, 360)) as x:
        run = _soak(args, Path(tmp), x.display)
    checks = _verdict(run, args.settle)
    drops = [(s["t"], s["dropped"]) for s in run["samples"] if s["dropped"] is not None]
    at_minute: dict[int, int] = {}
    for t, d in drops:  # the count at each minute's first sample
        at_minute.setdefault(int(t // 60), d)
    counts = [at_minute[k] for k in sorted(at_minute)]
    per_min = [b - a for a, b in itertools.pairwise(counts)]
    print(f"\n# {datetime.date.today()}: {args.minutes:g} min, {run['osc_sent']} OSC datagrams, "
          f"{run['stdin_sent']} stdin lines; events: {run['events']}")  # fmt: skip
    print(f"# frames dropped in each minute: {per_min}")
    for line in run["summary"]:
        print(f"# player: {line}")
    for what, held, figures in checks:
        print(f"{'ok  ' if held else 'FAIL'} {what}: {figures}")
    if args.json is not None:
        args.json.write_text(json.dumps({**run, "checks": checks}, indent=1))
    return 0 if all(held for _, held, _ in checks) else 1


if __name__ == "__main__":
    sys.exit(main())
