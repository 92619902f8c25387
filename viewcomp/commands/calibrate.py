"""`viewcomp calibrate CAPTURE_DIR -o CALIB`: captures -> calibration bundle."""

from __future__ import annotations

import argparse

from viewcomp.commands._common import nonnegative, nonnegative_int


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "calibrate",
        help="turn a capture set into a calibration bundle",
        description="Fit both methods - the paper's (global colour mixing, response from the "
        "ramp, Phong power law) and the per-pixel one (per-pixel mixing and ambient, "
        "baseline + lobe specular fit) - and write one bundle file. Prints how well each "
        "fit went and ends with a verdict - good, usable or poor, with the reasons "
        "(exposure, noise, clipping, coverage and decoding in camera space, fit residuals "
        "against the captures' noise); refuses captures that make a fit impossible, naming "
        "the file.",
    )
    p.add_argument("capture_dir", help="capture-set folder (rig.toml, white/, screen/)")
    p.add_argument("-o", "--output", required=True, help="bundle file to write (exact path)")
    p.add_argument(
        "--paper-fit",
        choices=["all", "row"],
        default="all",
        help="paper's Phong regression over all pixels (Eq. 8, default) or the "
        "camera's row (Eq. 7)",
    )
    p.add_argument(
        "--lobe",
        choices=["auto", "half", "mirror"],
        default="auto",
        help="the specular lobe's angle: between the normal and the half vector (microfacet "
        "lobes), between the mirror direction and the view (Phong), or auto: the one that "
        "fits the camera's view better (default)",
    )
    p.add_argument(
        "--mixing-blur-px",
        type=nonnegative,
        default=None,
        metavar="PX",
        help="Gaussian blur sigma in projector pixels of the per-pixel colour mixing and "
        "ambient (default 3)",
    )
    p.add_argument(
        "--colour-guide-px",
        type=nonnegative_int,
        default=None,
        metavar="PX",
        help="smooth the per-pixel colour mixing, and the colour of the per-pixel gains (their "
        "shares of their sum; the sum keeps the texture), over windows of this radius "
        "(projector pixels) wherever the screen's colour is uniform, keeping its colour "
        "edges: a guided filter led by the screen's chromaticity, against a camera's noise. "
        "Default: 32 for camera-space captures, 0 (not) for projector-space ones",
    )
    p.add_argument(
        "--report",
        metavar="DIR",
        default=None,
        help="also write the verdict and pictures into DIR (replaced whole): calibration.json, "
        "exposure.png, residual.png (the model's error per pixel), gamut.png (the brightest "
        "white the screen can show per pixel)",
    )
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from viewcomp.calib.fit.calibrate import calibrate
    from viewcomp.calib.fit.pixel import DEFAULT_SMOOTH_PX
    from viewcomp.calib.io.captureset import read_capture_set
    from viewcomp.commands._common import Log

    _check_paths(args)
    log = Log()
    log(f"reading {args.capture_dir}")
    cs = read_capture_set(args.capture_dir)
    w, h = cs.rig.projector.resolution
    space = cs.rig.capture.space
    log(f"calibrating a {w}x{h} projector ({space} space captures, black: {cs.has_black})")
    smooth = DEFAULT_SMOOTH_PX if args.mixing_blur_px is None else args.mixing_blur_px
    lobe_param = None if args.lobe == "auto" else args.lobe
    maps: dict = {}
    cal = calibrate(
        cs,
        fit_mode=args.paper_fit,
        smooth_px=smooth,
        lobe_param=lobe_param,
        maps=maps,
        log=log,
        guide_px=args.colour_guide_px,
    )
    del cs  # the captures (1.2 GB at 3840x2160) are not needed to write the bundle
    log(f"writing {args.output}")
    cal.save(args.output)
    lobe = cal.pixel.lobe
    print(f"wrote {args.output} (methods: {', '.join(cal.methods)})")
    if cal.paper is not None:
        f = cal.paper.fit
        print(
            f"  paper: log S = log(k_s i_s) + gamma log(R.V) over {f.samples} pixels; "
            f"gamma {_v(f.gamma)}, R^2 {_v(f.r2)}, rms {_v(f.rms)} (log units)"
        )
    else:
        print(
            f"  paper: not fitted ({cal.info.get('paper_error')}); the bundle holds the "
            "per-pixel method alone"
        )
    other = "mirror" if lobe.param == "half" else "half"
    print(
        f"  per-pixel: s = b + lobe({lobe.param} angle), tabulated; baseline "
        f"{_v(lobe.baseline)}, peak {_v(lobe.peak)}; rms {_v(lobe.rms)} (on the same "
        f"samples: {other} angle {_v(lobe.rms_other)}, b + kappa (R.V)^gamma "
        f"{_v(lobe.rms_phong)}, power law {_v(lobe.rms_power_law)}); {lobe.message}"
    )
    clipped = int(cal.info.get("clipped_pixels", 0))
    if clipped:
        print(
            f"  {clipped} pixels clipped in some capture were left out of the fits; "
            "capture with --hdr to measure them"
        )
    print(f"  projector response from the white ramp: rms misfit {cal.pixel.response_rms:.4f}")
    geo = cal.info.get("geometry")
    if geo:
        cb, m = geo.get("chessboard", {}), geo.get("map", {})
        print(
            f"  geometry (camera space): chessboard {cb.get('corners')} corners, Zhang "
            f"reprojection {cb.get('zhang_rms_px')} px RMS; Gray-code map vs chessboard "
            f"{m.get('chessboard_rms_px')} px RMS; lens {m.get('distortion')}; largest frame "
            f"shift {geo.get('max_frame_shift_px')} px"
        )
        ph = geo.get("phase")
        if ph:
            print(
                f"  phase shifting ({ph['period_px']}-px period, {ph['shifts']} shifts): "
                f"{ph['decoded_fraction_of_lit']:.1%} of the lit camera pixels at sub-pixel "
                f"positions, unwrapped by {ph['graycode_planes_used']} Gray-code planes "
                f"({ph['graycode_planes_dropped']} too fine for the camera, dropped); "
                + (
                    "the map is fitted to them"
                    if ph.get("used_for_map")
                    else "the camera resolves the whole Gray code, whose pixels the map keeps"
                )
            )
    _verdict(cal, maps, args.report, log)
    return 0


def _verdict(cal, maps: dict, report: str | None, log) -> None:
    """Print the verdict and its reasons; write the report folder when asked."""
    from viewcomp.calib.eval.verdict import judge

    verdict = judge(cal)
    print(f"verdict: {verdict.level.upper()} calibration")
    for reason in verdict.reasons:
        print(f"  - {reason}")
    if verdict.paper_level is not None and verdict.paper_level != "good":
        print(f"  (the paper's method alone: {verdict.paper_level})")
    if report is not None:
        from viewcomp.calib.eval.calreport import write_calibration_report

        log(f"writing the report {report}")
        files = write_calibration_report(report, cal, verdict, maps)
        print(f"report: {', '.join(str(f) for f in files)}")


def _v(a) -> str:
    return "(" + ", ".join("-" if x is None else f"{x:.3g}" for x in a) + ")"


def _check_paths(args: argparse.Namespace) -> None:
    """The bundle is never the capture set, a file in it or its folder (before any work)."""
    from viewcomp.commands._common import check_output_file

    check_output_file(args.output, args.capture_dir, make_parents=True)
    if args.report is not None:
        from viewcomp.commands._common import check_output_folder

        check_output_folder(args.report, args.capture_dir, args.output)
