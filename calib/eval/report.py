"""Writing the evaluation's report: report.json, report.md and PNG plots."""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from viewcomp.calib.io.atomic import atomic_open, write_text_atomic
from viewcomp.calib.io.imageio import to_linear, write_png

if TYPE_CHECKING:
    from viewcomp.calib.eval.evaluate import World

COLUMNS = ("original", "paper_90", "paper_theta", "pixel_90", "pixel_theta", "oracle")


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig: Any, path: Path) -> None:
    with atomic_open(path) as f:
        fig.savefig(f, format="png", dpi=110, bbox_inches="tight")


def plot_phong(world: World, path: Path, screen: str = "magenta") -> dict[str, Any]:
    """log s against log R.V, with the paper's power law and the baseline + lobe fit.

    The samples are s = (L_c,U - A_c) / (L_w,U - A_w) over its maximum (gray captures,
    black captures removed), and both fits are made on these very samples.
    """
    from viewcomp.calib.fit.lobe import fit_lobe
    from viewcomp.calib.fit.paper import fit_phong
    from viewcomp.calib.sim.simulate import capture_patterns
    from viewcomp.calib.sim.simulator import white_screen

    plt = _plt()
    case = world.case(screen)
    g = case.cal.pixel.geometry
    rv = g.rv(g.camera)

    def lin(scr: Any) -> dict[str, np.ndarray]:
        raw = capture_patterns(world.sim, scr)
        return {k: to_linear(raw[k], world.sim.response).astype(np.float64) for k in raw}

    c, w = lin(case.screen), lin(white_screen())
    s = (c["gray"] - c["black"]) / np.maximum(w["gray"] - w["black"], 1e-6)
    top = s.reshape(-1, 3).max(axis=0)
    power = fit_phong(s / top, rv, "all")
    lobe = fit_lobe(s, g)
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.8))
    sel = (slice(None, None, 4), slice(None, None, 4))
    ok = rv[sel] > 0
    x = np.log(rv[sel][ok])
    xs = np.linspace(x.min(), 0, 200)
    for ch, ax in enumerate(axes):
        y = np.log(np.maximum(s[sel][ok][:, ch] / top[ch], 1e-6))
        ax.plot(x, y, ".", ms=1, alpha=0.3, color="0.4", label="s samples")
        ax.plot(
            xs,
            np.log(power.ksis[ch]) + power.gamma[ch] * xs,
            "r-",
            label=f"paper: power law (gamma {power.gamma[ch]:.1f})",
        )
        yl = lobe.baseline[ch] + lobe.at(g, g.camera)[sel][ok][:, ch]
        order = np.argsort(x)
        ax.plot(
            x[order],
            np.log(np.maximum(yl[order], 1e-9) / top[ch]),
            "b-",
            label=f"baseline + tabulated lobe ({lobe.param} angle)",
        )
        ax.set_title(f"{screen} screen, channel {'RGB'[ch]}")
        ax.set_xlabel("log R.V")
        ax.legend(loc="lower right", fontsize=7)
        if ch == 0:
            ax.set_ylabel("log s (relative to its maximum)")
    _save(fig, path)
    plt.close(fig)
    return {
        "screen": screen,
        "power_law_gamma": power.gamma.tolist(),
        "power_law_rms_log": power.rms.tolist(),
        "power_law_rms": lobe.rms_power_law.tolist(),
        "lobe_rms": lobe.rms.tolist(),
        "lobe_param": lobe.param,
        "lobe_rms_other_param": lobe.rms_other.tolist(),
        "phong_rms": [float(v) for v in lobe.rms_phong],
        "lobe_peak": lobe.peak.tolist(),
        "lobe_baseline": lobe.baseline.tolist(),
        "true_kappa_gamma": [case.screen.k_s / 0.85, case.screen.shininess],
        "note": "rms in units of s (both fits on the same samples); rms_log in log units",
    }


def plot_sweep(means: dict[str, dict[str, float]], path: Path) -> None:
    """Mean dE against viewing angle, one line per column."""
    plt = _plt()
    angles = [float(a) for a in means]
    fig, ax = plt.subplots(figsize=(7, 4))
    styles = {
        "original": "k:",
        "paper_90": "r--",
        "paper_theta": "r-",
        "pixel_90": "b--",
        "pixel_theta": "b-",
        "oracle": "g-",
    }
    for k, st in styles.items():
        ax.plot(angles, [means[a][k] for a in means], st, marker="o", ms=3, label=k)
    ax.set_xlabel("viewing angle (degrees; 90 = in front)")
    ax.set_ylabel("mean CIEDE2000 vs the white screen")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    _save(fig, path)
    plt.close(fig)


def image_grid(keep: dict[str, Any], path: Path) -> None:
    """Rows: angles; columns: ideal, original, paper_90, paper_theta, pixel_theta, oracle."""
    import cv2

    views = keep["views"]
    cols = ("ideal", "original", "paper_90", "paper_theta", "pixel_theta", "oracle")
    rows = []
    for a in sorted(views):
        tiles = []
        for c in cols:
            t = views[a][c].copy()
            cv2.putText(
                t,
                f"{c} @{a:g}",
                (6, 20),
                cv2.FONT_HERSHEY_SIMPLEX,
                0.55,
                (255, 255, 255),
                2,
                cv2.LINE_AA,
            )
            tiles.append(t)
        rows.append(np.concatenate(tiles, axis=1))
    grid = np.concatenate(rows, axis=0)
    s = min(1.0, 2400 / grid.shape[1])
    grid = cv2.resize(grid, None, fx=s, fy=s, interpolation=cv2.INTER_AREA)
    write_png(path, grid)


def plot_tradeoff(world: World, path: Path, screen: str = "magenta") -> list[dict[str, float]]:
    """Eq. 22's trade-off on the per-pixel model (clipped fraction and alpha as lambda and
    the black-lift weight mu vary), beside the per-pixel method's own choice (the smallest
    predicted colour error)."""
    from viewcomp.calib.comp.compensation import Compensation, thumbnail
    from viewcomp.calib.comp.tonemap import choose_tone_map
    from viewcomp.calib.eval.testimages import natural_images
    from viewcomp.calib.model.reference import tone_terms, white_response

    plt = _plt()
    case = world.case(screen)
    h, w = world.shape
    image = next(iter(natural_images(w, h).values()))
    eye = world.eye(60)
    comp = Compensation(case.cal, "pixel")
    thumb = thumbnail(image)
    small = comp._small_model(comp.base_model(), thumb.shape[:2])
    cw = white_response(small, thumb).astype(np.float64)
    _, m_inv, amb = comp._screen(small, eye)
    u, v, c = tone_terms(m_inv, cw, amb)
    out: list[dict[str, Any]] = []
    for lam in (0.03, 0.1, 0.3, 1.0, 3.0, 10.0):
        for mu in (0.0, 1.0):
            t = choose_tone_map(u, v, c, 0.0, 1.0, lam, beta_weight=mu, beta_scale=cw.mean())
            out.append(
                {"lambda": lam, "mu": mu, "alpha": t.alpha, "beta": t.beta, "clipped": t.clipped}
            )
    own = comp.tone_map(comp.base_model(), thumb, eye)
    out.append(
        {
            "rule": "predicted colour error",
            "alpha": own.alpha,
            "beta": own.beta,
            "clipped": own.clipped,
        }
    )
    fig, ax = plt.subplots(figsize=(6, 4))
    for mu, st in ((0.0, "o--"), (1.0, "s-")):
        pts = [r for r in out if r.get("mu") == mu]
        ax.plot(
            [r["clipped"] for r in pts], [r["alpha"] for r in pts], st, label=f"Eq. 22, mu = {mu:g}"
        )
        for r in pts:
            ax.annotate(f"λ={r['lambda']:g}", (r["clipped"], r["alpha"]), fontsize=7)
    ax.plot([own.clipped], [own.alpha], "k*", ms=12, label="per-pixel method's choice")
    ax.set_xlabel("E_u + E_l (fraction of pixel-channels clipped)")
    ax.set_ylabel("alpha (brightness kept)")
    ax.set_title(f"tone map trade-off, {screen} screen seen at 60")
    ax.legend()
    ax.grid(alpha=0.3)
    _save(fig, path)
    plt.close(fig)
    return out


def _fmt_table2(rows: list[dict[str, Any]]) -> str:
    head = "| screen | image | seen at | " + " | ".join(COLUMNS) + " | paper_60 | pixel_60 |"
    lines = [head, "|" + "---|" * (3 + len(COLUMNS) + 2)]
    for r in rows:
        s = r["sse"]
        vals = " | ".join(f"{s[k] / 1e6:.1f}" for k in (*COLUMNS, "paper_60", "pixel_60"))
        lines.append(f"| {r['screen']} | {r['image']} | {r['seen_at']} | {vals} |")
    return "\n".join(lines)


def _fmt_means(means: dict[str, dict[str, float]]) -> str:
    lines = ["| angle | " + " | ".join(COLUMNS) + " |", "|" + "---|" * (1 + len(COLUMNS))]
    for a, m in means.items():
        lines.append(f"| {a} | " + " | ".join(f"{m[k]:.2f}" for k in COLUMNS) + " |")
    return "\n".join(lines)


ADAPTED_NOTE = (
    "The *adapted* dE is the mean CIEDE2000 after the best uniform brightness scale s in "
    "[1/4, 4] of the seen image (linear light: the eye adapts to the overall level); `limit` "
    "is the per-pixel physical limit under it (docs/EVALUATION.md)."
)


def _fmt_adapted(means: dict[str, dict[str, float]]) -> str:
    cols = [k for k in next(iter(means.values()))]
    lines = ["| angle | " + " | ".join(cols) + " |", "|" + "---|" * (1 + len(cols))]
    for a, m in means.items():
        lines.append(f"| {a} | " + " | ".join(f"{m[k]:.2f}" for k in cols) + " |")
    return "\n".join(lines)


def write_report(out: Path, report: dict[str, Any], world: World, keep: dict[str, Any]) -> None:
    """report.json, report.md and the plots into ``out``."""
    md = ["# viewcomp evaluation (the paper's Section 5, in simulation)", ""]
    cfg = report["config"]
    md += [
        f"Projector {cfg['projector'][0]}x{cfg['projector'][1]}, vertical fov "
        f"{cfg['projector_fov_y']:g} deg; glossy screens (k_s, shininess) = {cfg['gloss']}; "
        f"seed {cfg['seed']}; tone map: the paper's method Eq. 22 exactly (lambda = "
        f"{cfg['lambda']:g}), the per-pixel method and the oracle the smallest predicted "
        "colour error (the oracle predicting with the true model).",
        "",
        "Every number compares what an ideal eye (no noise, no vignetting, 8-bit sRGB) sees of "
        "the real screen with what it sees of the matte white screen showing the original "
        "image (T_i), from the same eye position. `*_theta` = compensated for the angle the "
        "row is seen at; `*_60` = compensated for 60 (the paper's T_60 column); `oracle` = "
        "the simulator's true model inverted exactly per pixel with the per-pixel tone-map "
        "rule.",
        "",
    ]
    if "table2" in report:
        md += ["## Table 2 protocol: sum of squared errors (Eq. 26), 8-bit units, x 10^6", ""]
        md += [_fmt_table2(report["table2"]), ""]
        md += [
            "Criteria (counts of rows):",
            "",
            "```",
            json.dumps(report["table2_checks"], indent=1),
            "```",
            "",
        ]
        md += [
            "Share of the gap between paper_90 and the oracle closed (SSE, mean over rows): "
            + json.dumps({k: round(v, 3) for k, v in report["table2_gap_closed_sse"].items()}),
            "",
        ]
    if "sweep" in report:
        plot_sweep(report["sweep_mean_de"], out / "error_vs_angle.png")
        md += ["## Angle sweep: mean CIEDE2000 over screens and natural images", ""]
        md += [_fmt_means(report["sweep_mean_de"]), "", "![](error_vs_angle.png)", ""]
        if "sweep_mean_adapted_de" in report:
            md += ["Adapted dE, the same columns, and the per-pixel limit. " + ADAPTED_NOTE, ""]
            md += [_fmt_adapted(report["sweep_mean_adapted_de"]), ""]
        md += ["Criteria:", "", "```", json.dumps(report["sweep_checks"], indent=1), "```", ""]
        md += [
            "Share of the gap between paper_90 and the oracle closed (dE, mean over rows): "
            + json.dumps({k: round(v, 3) for k, v in report["sweep_gap_closed_de"].items()}),
            "",
        ]
        if keep.get("views"):
            image_grid(keep, out / "grid.png")
            md += [
                f"Before/after ({keep['screen']} screen, image {keep['image']}):",
                "",
                "![](grid.png)",
                "",
            ]
    report["phong_fit"] = plot_phong(world, out / "phong_fit.png")
    md += [
        "## The specular fit",
        "",
        "![](phong_fit.png)",
        "",
        "```",
        json.dumps(report["phong_fit"], indent=1),
        "```",
        "",
    ]
    report["tone_tradeoff"] = plot_tradeoff(world, out / "tonemap_tradeoff.png")
    md += ["## Tone map trade-off", "", "![](tonemap_tradeoff.png)", ""]
    md += [f"Run time: {report['seconds']} s.", ""]
    write_report_files(out, report, md)


def write_materials_report(out: Path, report: dict[str, Any]) -> None:
    """report.json and report.md of the materials protocol into ``out``."""
    cfg = report["config"]
    md = [
        "# viewcomp evaluation on measured materials",
        "",
        f"Projector {cfg['projector'][0]}x{cfg['projector'][1]} (DLP-like response), seed "
        f"{cfg['seed']}, materials from {cfg['folder']}. Each material is captured in HDR and "
        "in 8 bits at the highest exposure at which nothing clips, then calibrated as "
        "`viewcomp calibrate` does. Numbers: mean CIEDE2000 over the natural images against "
        "the matte white screen seen from the same eye; `oracle` = the true model inverted "
        "exactly with the (alpha, beta) of smallest true error. Gap closed = sum over the "
        "angles off 90 of (pixel_90 - pixel_theta) / (pixel_90 - oracle).",
        "",
        "| material | capture | peak/diffuse | status | lobe | lobe rms (table / other angle "
        "/ b + kappa (R.V)^gamma / power law), mean over channels | gap closed | theta < 90 "
        "at every angle off 90 |",
        "|---|---|---:|---|---|---|---:|---|",
    ]
    for e in report["materials"]:
        status = "refused: " + str(e["refused"]) if e["refused"] else "calibrated"
        if e.get("paper_error"):
            status += " (per-pixel only)"
        lobe, summ = e.get("lobe"), e.get("summary")
        rms = (
            " / ".join(
                f"{np.nanmean(np.asarray(lobe[k], dtype=float)):.4f}"
                for k in ("rms", "rms_other_param", "rms_phong", "rms_power_law")
            )
            if lobe
            else "-"
        )
        gap = (
            "-"
            if not summ
            else ("no gap" if summ["gap_closed"] is None else f"{summ['gap_closed']:.2f}")
        )
        beats = str(all(summ["theta_beats_90"].values())) if summ else "-"
        md.append(
            f"| {e['material']} | {e['capture']} | {e['peak_ratio']:.0f} | {status} | "
            f"{lobe['param'] if lobe else '-'} | {rms} | {gap} | {beats} |"
        )
    md += ["", "Mean dE per angle (pixel_90 / pixel_theta / oracle; paper_90 / paper_theta):", ""]
    for e in report["materials"]:
        summ = e.get("summary")
        if not summ:
            continue
        md.append(
            f"- {e['material']} ({e['capture']}): "
            + "; ".join(
                f"{a}: {m['pixel_90']:.2f} / {m['pixel_theta']:.2f} / {m['oracle']:.2f}"
                + (f"; {m['paper_90']:.2f} / {m['paper_theta']:.2f}" if "paper_90" in m else "")
                for a, m in summ["mean_de"].items()
            )
        )
    md += ["", "Adapted dE per angle, each column and the per-pixel limit. " + ADAPTED_NOTE, ""]
    for e in report["materials"]:
        summ = e.get("summary")
        if summ and summ.get("mean_ade"):
            md += [f"{e['material']} ({e['capture']}):", "", _fmt_adapted(summ["mean_ade"]), ""]
    md += [
        "",
        "Criteria over the glossy materials (peak >= 10 x diffuse):",
        "",
        "```",
        json.dumps(report["materials_checks"], indent=1),
        "```",
        "",
        f"Run time: {report['seconds']} s.",
        "",
    ]
    write_report_files(out, report, md)


def write_audience_report(out: Path, report: dict[str, Any]) -> None:
    """report.json and report.md of the audience protocol into ``out``."""
    cfg = report["config"]
    md = [
        "# viewcomp evaluation: several viewers at once, and a tracked viewer",
        "",
        f"Projector {cfg['projector'][0]}x{cfg['projector'][1]}, seed {cfg['seed']}, "
        f"{cfg['capture_space']} space, viewers at {cfg['viewer']['distance']} m. Each zone's "
        f"audience compensation uses {cfg['audience_viewers']} viewers spread over it; every "
        f"column is judged at {cfg['judged_at']} angles evenly over the zone (mean CIEDE2000 "
        "against the white screen seen from the same eye). Mean over the sweep's glossy "
        "screens and natural images of each row's zone mean and zone worst:",
        "",
        "| zone | | pixel_90 | pixel_centre | pixel_audience | oracle (per viewer) |",
        "|---|---|---:|---:|---:|---:|",
    ]
    for name, z in report["zone_summary"].items():
        for what in ("mean", "worst"):
            m = z[what]
            md.append(
                f"| {name} | {what} | {m['pixel_90']:.2f} | {m['pixel_centre']:.2f} | "
                f"{m['pixel_audience']:.2f} | {m['oracle']:.2f} |"
            )
    md += [
        "",
        "Criteria (rows where they hold, of all rows; and on the means):",
        "",
        "```",
        json.dumps(
            {
                k: {c: v for c, v in z.items() if c not in ("mean", "worst")}
                for k, z in report["zone_summary"].items()
            },
            indent=1,
        ),
        "```",
        "",
    ]
    walk = report.get("walk")
    if walk:
        s = walk["summary"]
        md += [
            f"Tracked walk ({s['screen']} screen, {s['image']}, {s['frames_judged']} frames "
            f"judged, the tracked eye {s['delay_frames']} frames late, the walk scaled by "
            f"{walk['scale']:.3f}): mean dE tracked {s['mean']['tracked']:.2f}, exact eye "
            f"{s['mean']['exact']:.2f}, 90 degrees {s['mean']['pixel_90']:.2f}; 95th "
            f"percentile {s['p95']['tracked']:.2f} / {s['p95']['exact']:.2f} / "
            f"{s['p95']['pixel_90']:.2f}. Over time (t s, true angle, tracked angle, dE tracked "
            "/ exact / 90):",
            "",
            "| t | angle | tracked | tracked | exact | 90 |",
            "|---:|---:|---:|---:|---:|---:|",
        ]
        for r in walk["rows"]:
            d = r["de"]
            md.append(
                f"| {r['t']:.1f} | {r['angle']:.1f} | {r['tracked_angle']:.1f} | "
                f"{d['tracked']:.2f} | {d['exact']:.2f} | {d['pixel_90']:.2f} |"
            )
        md.append("")
    md += [f"Run time: {report['seconds']} s.", ""]
    write_report_files(out, report, md)


def write_report_files(out: Path, report: dict[str, Any], md: list[str]) -> None:
    """report.json (finite floats only) and report.md (the lines ``md``) into ``out``."""
    from viewcomp.calib.eval.evaluate import dumps

    write_text_atomic(out / "report.json", dumps(report))
    write_text_atomic(out / "report.md", "\n".join(md))
