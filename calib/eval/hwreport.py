"""report.json and report.md of `viewcomp evaluate --protocol hardware`."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from viewcomp.calib.eval.hardware import WITHIN
from viewcomp.calib.eval.report import write_report_files


def _cell(row: dict[str, Any], angle: str) -> str:
    e = row["emulated"][angle]["compensated"]
    i = row["ideal"][angle]["compensated"]
    ea = row["emulated"][angle].get("compensated_adapted")
    adapted = f", adapted {ea:.2f}" if ea is not None else ""
    colour = ""
    if "ideal_colour" in row:  # a mono camera's row: the ideal colour camera's beside
        c = row["ideal_colour"][angle]["compensated"]
        colour = f"; ideal colour camera {c:.2f}, {e / c:.3f}"
    return f"{e:.2f} / {i:.2f} ({e / i:.3f}{adapted}{colour})"


def write_hardware_report(out: Path, report: dict[str, Any]) -> None:
    """The table of profiles x screens x captures into ``out``."""
    cfg = report["config"]
    w, h = cfg["projector"]
    md = [
        "# viewcomp on emulated hardware",
        "",
        f"Projector {w}x{h} (an emulated DLP: colour sub-frames, PWM bit planes, 2-4 refreshes "
        f"of latency), seed {cfg['seed']}. Each row: `viewcomp capture`'s procedure on the "
        "emulated devices, `calibrate`, the per-pixel compensation of natural images, and what "
        "a viewer sees through the emulator's physics. Numbers: mean CIEDE2000 against the "
        "white screen, emulated captures / ideal projector-space captures of the same world "
        "by a camera of the same kind (ratio; the criterion is "
        f"<= {WITHIN} at 60 and 125 degrees; a mono camera's rows add the ideal colour "
        "camera's, what seeing no colour costs). Capture time: the "
        "emulated devices' clock, what the capture would take on the real ones.",
        "",
        "| profile | screen | capture | status | capture time (s) | 60 deg | 90 deg | 125 deg |",
        "|---|---|---|---|---:|---|---|---|",
    ]
    for r in report["hardware"]:
        if r["refused"]:
            md.append(
                f"| {r['profile']} | {r['screen']} | {r['capture']} | refused: "
                f"{r['refused']} | - | - | - | - |"
            )
            continue
        md.append(
            f"| {r['profile']} | {r['screen']} | {r['capture']} | calibrated | "
            f"{r['capture_seconds']:.0f} | {_cell(r, '60')} | {_cell(r, '90')} | "
            f"{_cell(r, '125')} |"
        )
    checks = report["hardware_checks"]
    md += [
        "",
        f"Refused: {len(checks['refused'])} ({', '.join(checks['refused']) or 'none'}). "
        f"Every calibrated row within {WITHIN} of ideal at 60 and 125 degrees, none refused: "
        f"{checks['within']}.",
        "",
        f"Run time: {report['seconds']} s.",
        "",
    ]
    write_report_files(out, report, md)
