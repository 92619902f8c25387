"""Small helpers shared by the sub-commands: argument groups, parsing and progress lines.

Each option that several commands take is declared once here, so that it has one name, one
meaning and one help text everywhere: :func:`add_eye_arguments` (``--angle``/``--eye``),
:func:`add_tone_arguments` (``--method``, ``--lambda``, ``--smooth``) and
:func:`add_simulator_arguments` (``--screen``, ``--gloss``, ``--space``, ``--seed``,
``--size``).
"""

from __future__ import annotations

import argparse
import math
import sys
import time

import numpy as np

from viewcomp.calib.errors import UsageError

#: The simulated screen without --screen and --gloss.
DEFAULT_SCREEN = "magenta"
DEFAULT_GLOSS = "glossy"


def nonnegative(text: str) -> float:
    """An argparse type: a finite number >= 0."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(v) or v < 0:
        raise argparse.ArgumentTypeError(f"expected a finite number >= 0, got {text!r}")
    return v


def finite(text: str) -> float:
    """An argparse type: a finite number."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return v


def nonnegative_int(text: str) -> int:
    """An argparse type: an integer >= 0."""
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if v < 0:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 0, got {text!r}")
    return v


#: An argparse type: a random seed, an integer >= 0.
seed = nonnegative_int


def positive(text: str) -> float:
    """An argparse type: a finite number > 0."""
    v = finite(text)
    if v <= 0:
        raise argparse.ArgumentTypeError(f"expected a number > 0, got {text!r}")
    return v


def add_force_argument(p: argparse.ArgumentParser, what: str) -> None:
    """``--force``: replace an existing ``what`` folder whole instead of refusing."""
    p.add_argument(
        "--force",
        action="store_true",
        help=f"replace an existing {what} in OUT_DIR whole (without it a non-empty OUT_DIR "
        "is refused)",
    )


def check_output_file(output: str, *inputs: str | None, make_parents: bool = False) -> None:
    """Refuse an output file that is, or resolves to, an input or lies in an input folder;
    a folder; or one whose folder is missing (unless ``make_parents``). OutputError."""
    from viewcomp.calib.io.paths import check_output

    check_output(output, [i for i in inputs if i], make_parents=make_parents)


def check_output_folder(
    out_dir: str, *inputs: str | None, force: bool | None = None, what: str = "folder"
) -> None:
    """Refuse an output folder that is a file, an input or inside one; with ``force`` given
    (commands that replace their folder whole), a non-empty folder unless ``force``, and a
    folder inside a capture set (or, unless ``what`` is one, a capture set) always.
    OutputError."""
    from viewcomp.calib.errors import OutputError
    from viewcomp.calib.io.captureset import RIG_FILE
    from viewcomp.calib.io.paths import check_output

    out = check_output(out_dir, [i for i in inputs if i], folder=True)
    if force is None:
        return
    parent = out.resolve().parent
    if (parent / RIG_FILE).is_file():
        raise OutputError(
            f"output folder {out} is inside the capture set {parent} (it has {RIG_FILE}): "
            "writing there would replace its captures - choose a folder outside it"
        )
    if what != "capture set" and (out / RIG_FILE).is_file():
        raise OutputError(
            f"output folder {out} is a capture set (it has {RIG_FILE}): writing the {what} "
            "there would replace its captures - choose another folder"
        )
    if out.is_dir() and any(out.iterdir()) and not force:
        raise OutputError(
            f"output folder {out} already holds files: refusing to write into it - choose a "
            f"new or empty folder, or give --force to replace the {what} there whole"
        )


def add_eye_arguments(
    p: argparse.ArgumentParser,
    *,
    required: bool = False,
    angle_default: float | None = None,
    angle_note: str = "",
    track: bool = False,
    audience: bool = False,
) -> None:
    """Where the viewer is: ``--angle DEG`` or ``--eye X,Y,Z`` (and ``--track CSV`` with
    ``track``, ``--audience SPEC`` with ``audience``), mutually exclusive. ``args.eye`` and
    ``args.audience`` stay text: parse them with :func:`parse_vec3` and
    :func:`viewcomp.calib.world.audience.parse_audience`.
    """
    where = p.add_mutually_exclusive_group(required=required)
    default = f"; default {angle_default:g}" if angle_default is not None else ""
    where.add_argument(
        "--angle",
        type=float,
        default=angle_default,
        metavar="DEG",
        help="viewing angle in degrees (90 = in front, < 90 to the audience's right"
        f"{default}{angle_note})",
    )
    where.add_argument(
        "--eye",
        metavar="X,Y,Z",
        help="eye position X,Y,Z in metres (world frame, screen at z = 0, +z toward the audience)",
    )
    if track:
        where.add_argument(
            "--track", metavar="CSV", help="CSV of (seconds, degrees) rows: the angle over time"
        )
    if audience:
        where.add_argument(
            "--audience",
            metavar="SPEC",
            help="several viewers at once (pixel method): a zone A:B[:N] of N viewers spread "
            "over A..B degrees (N default 7), or angles / X,Y,Z eyes separated by ';', each "
            'optionally weighted with @W, e.g. 60:120, "60;90;120", "0.2,0.03,0.5;-0.2,0.03,0.5"; '
            "the light per pixel is the least-squares best for all of them",
        )


def add_tone_arguments(p: argparse.ArgumentParser, *, smooth: bool = True) -> None:
    """The method and the tone map: ``--method``, ``--lambda`` (``args.lam``, None for the
    default) and, with ``smooth``, ``--smooth`` (the tone map's time constant in seconds)."""
    p.add_argument("--method", choices=["pixel", "paper"], default="pixel", help="default: pixel")
    p.add_argument(
        "--lambda",
        dest="lam",
        type=nonnegative,
        metavar="L",
        default=None,
        help="tone-map brightness weight (Eq. 22), default 1",
    )
    if smooth:
        p.add_argument(
            "--smooth",
            type=nonnegative,
            metavar="SECONDS",
            default=0.5,
            help="time constant in seconds of the tone map's smoothing over video frames "
            "(default 0.5; 0: none)",
        )


def add_tone_choice(p: argparse.ArgumentParser, where: str = "") -> None:
    """``--tone paper|global|adaptive`` (``args.tone``, None: the method's); ``where`` adds
    what it means for this command to the help."""
    p.add_argument(
        "--tone",
        choices=["paper", "global", "adaptive"],
        default=None,
        help="how the tone map is chosen: paper (Eq. 21/22), global (one alpha, beta of the "
        "smallest predicted error: the pixel method's default) or adaptive (a smooth gain and "
        "offset field with a hue-keeping soft clip into each pixel's reach, mixed per shot with "
        f"a per-channel clip; pixel method, one eye){where}",
    )


def check_tone(args: argparse.Namespace) -> None:
    """``--tone`` against ``--method``: global and adaptive need the pixel method.

    Raises:
        UsageError: naming the option and the fix.
    """
    from viewcomp.calib.errors import UsageError

    if args.tone in ("global", "adaptive") and args.method == "paper":
        raise UsageError(f"--tone {args.tone} needs --method pixel (the paper's: --tone paper)")


def add_simulator_arguments(
    p: argparse.ArgumentParser | argparse._ArgumentGroup,
    *,
    screen: bool = True,
    gloss: bool = True,
    space: bool = False,
    size: str | None = "--size",
    material: bool = False,
) -> None:
    """The simulated world: ``--screen`` (a name or R,G,B: :func:`screen_colour`),
    ``--gloss``, ``--space``, ``--seed`` and the projector grid (``size`` names the flag;
    None for none; the value is WxH text, see :func:`parse_size`). With ``material``, also
    ``--material`` (a measured material instead of ``--screen``/``--gloss``) and
    ``--projector``. ``--screen`` and ``--gloss`` are None when not given (so that
    ``--material`` can refuse them): read them through :func:`simulated_screen`."""
    from viewcomp.calib.sim.simulator import GLOSS_PRESETS, PROJECTOR_PRESETS, SCREEN_COLOURS

    if screen:
        p.add_argument(
            "--screen",
            default=None,
            help=f"simulated screen colour: {', '.join(SCREEN_COLOURS)}, or R,G,B albedos in "
            "0..1 (default: magenta)",
        )
    if gloss:
        p.add_argument(
            "--gloss",
            default=None,
            choices=sorted(GLOSS_PRESETS),
            help="default: glossy",
        )
    if material:
        p.add_argument(
            "--material",
            metavar="PATH.npz",
            default=None,
            help="a measured material (a neural-BRDF .npz, e.g. of shared/data/materials/) as "
            "the screen, lit through a projector lens 15 mm across; not with --screen/--gloss",
        )
        p.add_argument(
            "--projector",
            choices=sorted(PROJECTOR_PRESETS),
            default=None,
            help="the simulated projector's response: dlp (black leak 2.5-3.5%%, a kink near "
            "white, per channel) or default (a power law); default: dlp with --material, "
            "default otherwise",
        )
    if space:
        p.add_argument(
            "--space",
            default="projector",
            choices=["projector", "camera"],
            help="projector: captures already on the projector grid; camera: raw camera "
            "frames, rectified by calibrate (lens, chessboard, Gray code; slower) "
            "(default: projector)",
        )
    p.add_argument("--seed", type=seed, default=0, help="simulator noise seed (default 0)")
    if size is not None:
        p.add_argument(
            size,
            default=None,
            metavar="WxH",
            help="simulated projector grid WxH (default 640x320, the paper's)",
        )


def simulated_screen(
    args: argparse.Namespace,
) -> tuple[str | tuple[float, float, float], str, str | None, str]:
    """The options of :func:`add_simulator_arguments` that make the screen, defaults filled
    in: ``(colour, gloss, material path or None, projector preset name)`` (a command without
    ``--gloss``, ``--material`` or ``--projector`` gets glossy, None, default).

    Raises:
        UsageError: ``--material`` given with ``--screen`` or ``--gloss``.
    """
    screen = getattr(args, "screen", None)
    gloss = getattr(args, "gloss", None)
    material = getattr(args, "material", None)
    if material is not None and (screen is not None or gloss is not None):
        given = " and ".join(f for f, v in (("--screen", screen), ("--gloss", gloss)) if v)
        raise UsageError(
            f"--material replaces {given}: give either a measured material or an analytic "
            "screen, not both"
        )
    projector = getattr(args, "projector", None) or ("dlp" if material else "default")
    return (
        screen_colour(screen if screen is not None else DEFAULT_SCREEN),
        gloss if gloss is not None else DEFAULT_GLOSS,
        material,
        projector,
    )


def screen_colour(text: str) -> str | tuple[float, float, float]:
    """A ``--screen`` value: a colour name as given, or R,G,B parsed."""
    from viewcomp.calib.sim.simulator import SCREEN_COLOURS

    return text if text in SCREEN_COLOURS else parse_rgb(text)


def parse_size(text: str) -> tuple[int, int]:
    """'WxH' -> (w, h), both positive."""
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise UsageError(f"a size is WIDTHxHEIGHT in pixels, e.g. 1280x720; got {text!r}") from None
    if w < 2 or h < 2:
        raise UsageError(f"a size needs at least 2x2 pixels, got {text!r}")
    from viewcomp.calib.io.imageio import MAX_IMAGE_PIXELS, MAX_IMAGE_SIDE

    if w > MAX_IMAGE_SIDE or h > MAX_IMAGE_SIDE or w * h > MAX_IMAGE_PIXELS:
        raise UsageError(
            f"a size is at most {MAX_IMAGE_SIDE} pixels a side and "
            f"{MAX_IMAGE_PIXELS / 1e6:.0f} megapixels, got {text!r}"
        )
    return w, h


def parse_vec3(text: str, what: str = "an eye position") -> np.ndarray:
    """'X,Y,Z' -> (3,) float metres."""
    try:
        v = np.array([float(x) for x in text.split(",")])
    except ValueError:
        raise UsageError(f"{what} is X,Y,Z in metres, e.g. 0.1,0.0,0.5; got {text!r}") from None
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise UsageError(f"{what} is three numbers X,Y,Z in metres; got {text!r}")
    return v


def parse_rgb(text: str) -> tuple[float, float, float]:
    """'R,G,B' albedos in 0..1."""
    try:
        v = tuple(float(x) for x in text.split(","))
    except ValueError:
        raise UsageError(f"a screen colour is a name or R,G,B in 0..1; got {text!r}") from None
    if len(v) != 3 or not all(math.isfinite(x) and 0.0 <= x <= 1.0 for x in v):
        raise UsageError(f"a screen colour is a name or R,G,B in 0..1; got {text!r}")
    return v  # type: ignore[return-value]


class Log:
    """Progress lines on stderr with the elapsed time (quiet with ``quiet=True``)."""

    def __init__(self, quiet: bool = False) -> None:
        self.quiet = quiet
        self.t0 = time.perf_counter()

    def __call__(self, msg: str) -> None:
        if not self.quiet:
            print(f"[{time.perf_counter() - self.t0:6.1f} s] {msg}", file=sys.stderr, flush=True)
