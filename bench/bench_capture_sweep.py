"""Capture and calibrate on every emulated camera and surface: the sweep behind issue 20's
"no false refusal" table in docs/EVALUATION.md. Prints one JSON line per case to stdout.

Each case runs the command line a user runs, in a subprocess: ``viewcomp capture OUT
--emulate PROFILE [--hdr] (--screen magenta | --screen textured --gloss satin | --material
M.npz) --sim-size WxH --frames F --seed S --yes``, then, when the capture was written,
``viewcomp calibrate OUT -o OUT.npz``. Per case: the capture's outcome (its error's first
line when refused), the emulated devices' clock it printed, the wall time, and calibrate's
outcome (the verdict line, or its error).

With ``--bump PX``: the camera is bumped by PX camera px at the K-th pattern shown (``--bump-at
K:PX``) for K = 0, STEP, 2 STEP, ... until three captures in a row go through (K past the
procedure's last show); one line per K says whether it was refused as moved, naming which
capture. A capture that goes through before a later refused K is a bump the checks missed. Run from
the repository root::

    .venv/bin/python bench/bench_capture_sweep.py --materials DIR [--profiles webcam,dslr,mono12]
        [--modes 8bit,hdr] [--size 160x80] [--frames 2] [--seed 0] [--only NAME,...]
        [--bump 1.5 --bump-step 4]
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

BUILT_IN = {
    "magenta": ["--screen", "magenta"],
    "textured-satin": ["--screen", "textured", "--gloss", "satin"],
}


def _viewcomp() -> list[str]:
    return [sys.executable, "-m", "viewcomp"]


def _last_error(text: str) -> str:
    lines = [ln for ln in text.splitlines() if "error:" in ln]
    return lines[-1].split("error:", 1)[1].strip() if lines else text.strip().splitlines()[-1:][0]


MOVED_WORDS = ("moved", "lies ", "no clear match")


def bump_sweep(
    profile: str, surface: list[str], hdr: bool, args: argparse.Namespace
) -> Iterator[dict]:
    """Yield one record per bump position K (see the module doc)."""
    k, passed = 0, 0
    while k <= 1000:
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / "caps"
            cmd = [*_viewcomp(), "capture", str(out), "--emulate", profile, *surface]
            cmd += ["--sim-size", args.size, "--frames", str(args.frames), "--seed", str(args.seed)]
            cmd += ["--yes", "--bump-at", f"{k}:{args.bump}"] + (["--hdr"] if hdr else [])
            cap = subprocess.run(cmd, capture_output=True, text=True, check=False)
        if cap.returncode == 0:  # past the last show, or a bump the checks missed
            yield {"k": k, "outcome": "captured"}
            passed += 1
            if passed == 3:
                return
            k += args.bump_step
            continue
        passed = 0
        err = _last_error(cap.stderr or cap.stdout)
        moved = any(w in err for w in MOVED_WORDS)
        yield {
            "k": k,
            "outcome": "refused as moved" if moved else "refused otherwise",
            "error": err,
        }
        k += args.bump_step


def run_case(
    profile: str, surface: list[str], hdr: bool, args: argparse.Namespace, tmp: Path
) -> dict:
    """Capture then calibrate one case; returns its record."""
    out = tmp / "caps"
    cmd = [*_viewcomp(), "capture", str(out), "--emulate", profile, *surface]
    cmd += [
        "--sim-size",
        args.size,
        "--frames",
        str(args.frames),
        "--seed",
        str(args.seed),
        "--yes",
    ]
    if hdr:
        cmd.append("--hdr")
    t0 = time.perf_counter()
    cap = subprocess.run(cmd, capture_output=True, text=True, check=False)
    rec: dict = {"wall_s": round(time.perf_counter() - t0, 1), "capture_rc": cap.returncode}
    clock = re.search(r"emulated devices' clock: ([0-9.]+) s", cap.stderr + cap.stdout)
    rec["clock_s"] = float(clock.group(1)) if clock else None
    if cap.returncode != 0:
        rec["capture"] = "refused: " + _last_error(cap.stderr or cap.stdout)
        return rec
    dimmed = re.search(r"dimmed[^\n]*", cap.stderr + cap.stdout)
    rec["capture"] = "captured" + (f" ({dimmed.group(0)[:120]})" if dimmed else "")
    bundle = tmp / "b.npz"
    cal = subprocess.run(
        [*_viewcomp(), "calibrate", str(out), "-o", str(bundle)],
        capture_output=True,
        text=True,
        check=False,
    )
    if cal.returncode != 0:
        rec["calibrate"] = "refused: " + _last_error(cal.stderr or cal.stdout)
    else:
        verdict = re.search(r"verdict: ([A-Z]+)", cal.stdout + cal.stderr)
        methods = re.search(r"\(methods: ([^)]*)\)", cal.stdout + cal.stderr)
        rec["calibrate"] = (verdict.group(1).lower() if verdict else "calibrated") + (
            f" ({methods.group(1)})" if methods else ""
        )
    return rec


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument(
        "--materials", type=Path, required=True, help="folder of measured .npz materials"
    )
    p.add_argument("--profiles", default="webcam,dslr,mono12")
    p.add_argument("--modes", default="8bit,hdr")
    p.add_argument("--size", default="160x80", help="projector (simulation) size WxH")
    p.add_argument("--frames", type=int, default=2)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--only", default="", help="comma-separated surfaces (default: all)")
    p.add_argument("--bump", type=float, default=0.0, help="bump PX camera px at each K (0: none)")
    p.add_argument("--bump-step", type=int, default=4, help="K's step with --bump")
    args = p.parse_args()
    surfaces = dict(BUILT_IN)
    for m in sorted(args.materials.glob("*.npz")):
        surfaces[m.stem] = ["--material", str(m)]
    only = [s for s in args.only.split(",") if s]
    for name, surface in surfaces.items():
        if only and name not in only:
            continue
        for profile in args.profiles.split(","):
            for mode in args.modes.split(","):
                if args.bump:
                    for rec in bump_sweep(profile, surface, mode == "hdr", args):
                        row = {"surface": name, "profile": profile, "mode": mode, **rec}
                        print(json.dumps(row), flush=True)
                    continue
                with tempfile.TemporaryDirectory() as tmp:
                    rec = run_case(profile, surface, mode == "hdr", args, Path(tmp))
                row = {"surface": name, "profile": profile, "mode": mode, **rec}
                print(json.dumps(row), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
