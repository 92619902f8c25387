"""The capture set: a folder of calibration captures (docs/INTERFACES.md).

```
rig.toml
white/{red,green,blue,gray,ramp}.png [white/black.png]     ideal matte white screen
screen/{red,green,blue,gray,ramp}.png [screen/black.png]   the real screen
[screen/chessboard.png, screen/graycode_XX.png ...]         extras, listed but not loaded
```

Images are PNG or TIFF (8- or 16-bit encoded camera values) or ``.npy`` (float32 linear).
Loaded images are float32 (H, W, 3) linear light in 0..1 camera units, decoded with the
camera's response from rig.toml.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from viewcomp.calib.io.atomic import atomic_dir, atomic_open
from viewcomp.calib.io.imageio import (
    IMAGE_SUFFIXES,
    CaptureError,
    clipped_mask,
    max_code_fraction,
    read_image,
    to_linear,
    write_npy,
    write_png,
)
from viewcomp.calib.io.paths import check_input_file, path_problem
from viewcomp.calib.io.patterns import PRIMARY_PATTERNS
from viewcomp.calib.world.rig import Rig, load_rig, rig_to_toml

REQUIRED = ("red", "green", "blue", "gray", "ramp")
OPTIONAL = ("black", *PRIMARY_PATTERNS)  # the primaries alone: a mono camera's set
SUBS = ("white", "screen")
RIG_FILE = "rig.toml"

_FIX = "run `viewcomp simulate` or `viewcomp capture`"
_NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")


@dataclass
class CaptureSet:
    """A loaded capture set.

    ``white[name]`` and ``screen[name]`` are float32 (H, W, 3) linear images, 0..1 camera
    units, for the names of ``REQUIRED`` and, when captured, ``black``. ``raw_max_fraction``
    maps (sub, name) to the fraction of pixel-channels at the maximum code (see
    :meth:`saturated`). ``extra[sub]`` lists the other image files (chessboard, Gray code),
    which are not loaded. ``path`` is the folder.
    """

    rig: Rig
    white: dict[str, np.ndarray]
    screen: dict[str, np.ndarray]
    raw_max_fraction: dict[tuple[str, str], float]
    path: Path
    extra: dict[str, list[Path]] = field(default_factory=dict)
    clipped: dict[tuple[str, str], np.ndarray] = field(default_factory=dict)

    def clipped_pixels(self) -> np.ndarray:
        """(H, W) bool: pixels clipped (a channel at the top code) in any loaded capture."""
        h, w = self.white["gray"].shape[:2]
        out = np.zeros((h, w), bool)
        for mask in self.clipped.values():
            if mask.shape == out.shape:
                out |= mask
        return out

    @property
    def has_black(self) -> bool:
        """Whether the optional black captures are present (always in both folders)."""
        return "black" in self.white

    @property
    def size(self) -> tuple[int, int]:
        """(width, height) of every image in pixels."""
        h, w = self.white["gray"].shape[:2]
        return (w, h)

    def images(self, sub: str) -> dict[str, np.ndarray]:
        """The loaded images of ``sub`` ("white" or "screen")."""
        if sub not in SUBS:
            raise ValueError(f'sub must be "white" or "screen", got {sub!r}')
        return self.white if sub == "white" else self.screen

    def saturated(self, sub: str, name: str) -> float:
        """Fraction 0..1 of the pixel-channels of ``sub/name`` at the maximum code (255 for
        8-bit, 65535 for 16-bit; 0 for linear ``.npy``, whose values above 1 are HDR light)."""
        key = (sub, name)
        if key not in self.raw_max_fraction:
            raise KeyError(f"no capture {sub}/{name} in {self.path}")
        return self.raw_max_fraction[key]


def find_capture(directory: str | Path, sub: str, name: str) -> Path | None:
    """The file ``directory/sub/name`` with suffix .png, .tif, .tiff or .npy, or None.

    Raises :class:`CaptureError` if more than one such file exists (which one is meant would
    be a guess).
    """
    folder = Path(directory) / sub
    # anything by that name counts (a folder, a broken link): reading it then says what it is
    candidates = [folder / f"{name}{s}" for s in IMAGE_SUFFIXES]
    found = [p for p in candidates if p.exists() or p.is_symlink()]
    if len(found) > 1:
        names = " and ".join(f"{sub}/{p.name}" for p in found)
        raise CaptureError(f"ambiguous: {names} both exist in {directory} - keep only one")
    return found[0] if found else None


def _size_error(rel: str, w: int, h: int, rig: Rig) -> CaptureError | None:
    if rig.capture.space == "projector":
        pw, ph = rig.projector.resolution
        if (w, h) != (pw, ph):
            return CaptureError(
                f"wrong size: {rel} is {w}x{h}, the projector grid is {pw}x{ph} (space = projector)"
            )
    else:
        cw, ch = rig.camera.resolution
        if (w, h) != (cw, ch):
            return CaptureError(
                f"wrong size: {rel} is {w}x{h}, the camera's resolution is {cw}x{ch} "
                "(space = camera)"
            )
    return None


def _same_size(
    rel: str, img: np.ndarray, rig: Rig, first: tuple[str, int, int] | None
) -> tuple[str, int, int]:
    """Check one image's size against the rig and the set's first image; returns the first."""
    h, w = img.shape[:2]
    err = _size_error(rel, w, h, rig)
    if err is not None:
        raise err
    if first is None:
        return (rel, w, h)
    if (w, h) != first[1:]:
        raise CaptureError(
            f"wrong size: {rel} is {w}x{h}, {first[0]} is {first[1]}x{first[2]} - all "
            "captures of a set must have one size"
        )
    return first


def _find_files(root: Path) -> dict[tuple[str, str], Path]:
    """(sub-folder, pattern) -> image file: every REQUIRED one in both sub-folders, each
    OPTIONAL one in both or in neither; else CaptureError naming what is missing."""
    files: dict[tuple[str, str], Path] = {}
    missing: list[str] = []
    for sub in SUBS:
        for name in REQUIRED:
            p = find_capture(root, sub, name)
            if p is None:
                missing.append(f"{sub}/{name}.png")
            else:
                files[(sub, name)] = p
    if missing:
        them = "it" if len(missing) == 1 else "them"
        raise CaptureError(
            f"not found: {', '.join(missing)} - the capture set needs {them}; {_FIX} (in {root})"
        )
    for name in OPTIONAL:
        found = {sub: find_capture(root, sub, name) for sub in SUBS}
        present = [(sub, p) for sub, p in found.items() if p is not None]
        if len(present) == 1:
            sub, p = present[0]
            other = "screen" if sub == "white" else "white"
            raise CaptureError(
                f"{name} is optional, but {sub}/{p.name} exists and "
                f"{other}/{name} is missing - capture it in both white/ and screen/ or in "
                f"neither (in {root})"
            )
        for sub, p in found.items():
            if p is not None:
                files[(sub, name)] = p
    return files


def read_capture_set(directory: str | Path) -> CaptureSet:
    """Read and validate a capture-set folder.

    Checks: rig.toml present and valid; every REQUIRED image in both white/ and screen/;
    ``black`` in both or in neither; one size for all images, equal to the projector's
    resolution for space = "projector" (the camera's for space = "camera"). Raises
    :class:`CaptureError` (or :class:`~viewcomp.calib.world.rig.RigError`) naming the file and fix.
    """
    root = Path(directory)
    problem = path_problem(root)
    if problem is None and not root.is_dir():
        problem = "is a file, not a folder"
    if problem is not None:
        what = (
            f"not found: capture set folder {root}"
            if problem == "not found"
            else (f"capture set folder {root}: {problem}")
        )
        raise CaptureError(f"{what} - give the folder written by {_FIX}")
    rig_file = root / RIG_FILE
    if (problem := path_problem(rig_file)) is not None:
        raise CaptureError(f"{problem}: {RIG_FILE} in {root} - the capture set needs it; {_FIX}")
    check_input_file(rig_file, "the rig file", f"a {RIG_FILE} text file", CaptureError)
    rig = load_rig(rig_file)

    files = _find_files(root)

    response = rig.camera.response_curve()
    loaded: dict[str, dict[str, np.ndarray]] = {sub: {} for sub in SUBS}
    fractions: dict[tuple[str, str], float] = {}
    clipped: dict[tuple[str, str], np.ndarray] = {}
    first: tuple[str, int, int] | None = None
    for (sub, name), p in files.items():
        rel = f"{sub}/{p.name}"
        try:
            raw = read_image(p)
        except CaptureError as exc:
            raise CaptureError(f"{exc} (capture {rel} in {root})") from None
        first = _same_size(rel, raw, rig, first)
        fractions[(sub, name)] = max_code_fraction(raw)
        clipped[(sub, name)] = clipped_mask(raw)
        loaded[sub][name] = to_linear(raw, response)

    known = set(REQUIRED) | set(OPTIONAL)
    extra: dict[str, list[Path]] = {}
    for sub in SUBS:
        folder = root / sub
        extra[sub] = sorted(
            p
            for p in folder.iterdir()
            if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES and p.stem not in known
        )
    return CaptureSet(
        rig=rig,
        white=loaded["white"],
        screen=loaded["screen"],
        raw_max_fraction=fractions,
        path=root,
        extra=extra,
        clipped=clipped,
    )


def _check_images(sub: str, images: Mapping[str, np.ndarray]) -> None:
    missing = [n for n in REQUIRED if n not in images]
    if missing:
        raise ValueError(f"write_capture_set: {sub} lacks {', '.join(missing)}")
    for name, img in images.items():
        if not _NAME_RE.match(name):
            raise ValueError(f"write_capture_set: bad image name {name!r} in {sub}")
        a = np.asarray(img)
        if a.ndim != 3 or a.shape[2] != 3:
            raise ValueError(f"write_capture_set: {sub}/{name} must be (H, W, 3), got {a.shape}")
        if a.dtype not in (np.uint8, np.uint16, np.float32):
            raise ValueError(
                f"write_capture_set: {sub}/{name} must be uint8 or uint16 (encoded) or float32 "
                f"(linear), got {a.dtype}"
            )


def write_capture_set(
    directory: str | Path,
    rig: Rig,
    white: Mapping[str, np.ndarray],
    screen: Mapping[str, np.ndarray],
) -> list[Path]:
    """Write a capture set: rig.toml, then one file per image, each atomically.

    ``white`` and ``screen`` map names to (H, W, 3) arrays: uint8/uint16 encoded camera values
    (written as PNG) or float32 linear values (written as ``.npy``). Both must hold every name
    of REQUIRED; ``black`` must be in both or neither; other names (chessboard, graycode_XX)
    are written as extras. Sizes are checked as :func:`read_capture_set` does.

    The set is written into a temporary folder that then replaces ``directory`` whole
    (:func:`~viewcomp.calib.io.atomic.atomic_dir`): an old capture set there leaves no file
    behind, and a failure (disk full, interrupted) leaves the old folder as it was. A
    non-empty folder without rig.toml is refused, so nothing that is not a capture set is
    replaced. Returns the written paths.
    """
    root = Path(directory)
    if root.exists() and not root.is_dir():
        raise CaptureError(f"cannot write a capture set to {root}: it is a file, not a folder")
    if root.is_dir() and any(root.iterdir()) and not (root / RIG_FILE).is_file():
        raise CaptureError(
            f"refusing to write a capture set into {root}: the folder is not empty and has no "
            f"{RIG_FILE}, so it does not look like a capture set - choose a new or empty folder"
        )
    _check_images("white", white)
    _check_images("screen", screen)
    for name in OPTIONAL:
        if (name in white) != (name in screen):
            raise ValueError(f"write_capture_set: {name} must be given for both white and screen")
    first: tuple[str, int, int] | None = None
    for sub, images in (("white", white), ("screen", screen)):
        for name, img in images.items():
            first = _same_size(f"{sub}/{name}", np.asarray(img), rig, first)

    with atomic_dir(root) as staging:
        written = _write_files(staging, rig, white, screen)
    return [root / p.relative_to(staging) for p in written]


def _write_files(
    folder: Path, rig: Rig, white: Mapping[str, np.ndarray], screen: Mapping[str, np.ndarray]
) -> list[Path]:
    """Write rig.toml and the images into the (new, empty) ``folder``; returns the paths."""
    written: list[Path] = []
    rig_path = folder / RIG_FILE
    with atomic_open(rig_path) as f:
        f.write(rig_to_toml(rig).encode("utf-8"))
    written.append(rig_path)
    for sub, images in (("white", white), ("screen", screen)):
        (folder / sub).mkdir()
        for name, img in images.items():
            a = np.asarray(img)
            target = folder / sub / f"{name}{'.npy' if a.dtype == np.float32 else '.png'}"
            if target.suffix == ".npy":
                write_npy(target, a)
            else:
                write_png(target, a)
            written.append(target)
    return written


def capture_set_from_raw(
    rig: Rig,
    white: Mapping[str, np.ndarray],
    screen: Mapping[str, np.ndarray],
    path: str | Path = "<memory>",
) -> CaptureSet:
    """A CaptureSet from raw images in memory (as `read_capture_set` would load them).

    ``white`` and ``screen`` map names to encoded uint8/uint16 (H, W, 3) camera images (or
    float32 linear); they are linearised with the rig's camera response.
    """
    _check_images("white", white)
    _check_images("screen", screen)
    response = rig.camera.response_curve()
    lin: dict[str, dict[str, np.ndarray]] = {"white": {}, "screen": {}}
    top: dict[tuple[str, str], float] = {}
    clipped: dict[tuple[str, str], np.ndarray] = {}
    for sub, images in (("white", white), ("screen", screen)):
        for name, raw in images.items():
            lin[sub][name] = to_linear(np.asarray(raw), response)
            top[(sub, name)] = max_code_fraction(np.asarray(raw))
            clipped[(sub, name)] = clipped_mask(np.asarray(raw))
    return CaptureSet(rig, lin["white"], lin["screen"], top, Path(path), clipped=clipped)
