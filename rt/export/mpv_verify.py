"""What an exported mpv shader must do, written into it, and how a check reads it back.

mpv 0.35 skips a hook whose ``//!BIND`` textures are missing without an error: a file cut
short before its ``//!TEXTURE`` blocks plays uncompensated with exit status 0. So the
export carries its own check value and an end marker (plain ``//`` comments: mpv parses
only ``//!`` lines), shared by :func:`viewcomp.rt.export.mpv.export_mpv_shader` (which
writes them) and :func:`viewcomp.rt.export.mpv_check.check_mpv` (which reads them):

- :func:`check_still`: a fixed colour ramp at the calibration grid's (W, H);
- :func:`block_means`: the mean output levels of :data:`BLOCKS` x :data:`BLOCKS` blocks x RGB
  of the hook's output for that still, from the numpy reference, as the line
  ``// viewcomp check: ...`` (:func:`check_line`, :func:`parse_check`);
- ``// viewcomp textures: N: NAME ...`` (:func:`texture_line`), in the header: the
  ``//!TEXTURE`` blocks the file holds, in order, the last one ending the file. (Not an
  end-of-file comment: mpv reads everything after the last ``//!TEXTURE``'s directives up
  to the next ``//!`` as its hex data, so a trailing comment makes mpv 0.35 reject the file:
  "Error while parsing TEXTURE body". The last block's hex complete for its SIZE and FORMAT
  is the end of the file.);
- :func:`structure_problems`: every bound and listed texture present and complete.
"""

from __future__ import annotations

import re

import numpy as np

BLOCKS = 4  # the check value: BLOCKS x BLOCKS blocks of the grid, mean level per channel
CHECK_PREFIX = "// viewcomp check: "
LIST_PREFIX = "// viewcomp textures: "
# Textures mpv itself provides to a hook (no //!TEXTURE block for them).
MPV_TEXTURES = frozenset(
    "HOOKED MAIN OUTPUT LUMA CHROMA RGB XYZ NATIVE LINEAR SIGMOID PREKERNEL POSTKERNEL "
    "SCALED ALPHA CHROMA_SCALED ALPHA_SCALED".split()
)
_BYTES = {"rgba8": 4, "rgba16": 8, "rgba16f": 8, "rgba32f": 16}  # per texel


def check_still(grid: tuple[int, int]) -> np.ndarray:
    """The check's still (H, W, 3) uint8 RGB for a (W, H) grid: red rising to the right,
    green rising downwards, blue falling to the right (every block a different colour)."""
    w, h = grid
    xx = np.arange(w, dtype=np.float64)[None, :] / max(w - 1, 1)
    yy = np.arange(h, dtype=np.float64)[:, None] / max(h - 1, 1)
    r = np.broadcast_to(32 + 192 * xx, (h, w))
    g = np.broadcast_to(32 + 192 * yy, (h, w))
    b = np.broadcast_to(224 - 160 * xx, (h, w))
    return np.rint(np.dstack([r, g, b])).astype(np.uint8)


def block_means(image: np.ndarray) -> np.ndarray:
    """(BLOCKS, BLOCKS, 3) float64 mean levels (0..255) of an (H, W, 3) image over a
    BLOCKS x BLOCKS grid of blocks (block edges at round(i H / BLOCKS), round(j W / BLOCKS))."""
    h, w = image.shape[:2]
    ys = np.rint(np.linspace(0, h, BLOCKS + 1)).astype(int)
    xs = np.rint(np.linspace(0, w, BLOCKS + 1)).astype(int)
    out = np.zeros((BLOCKS, BLOCKS, 3))
    for i in range(BLOCKS):
        for j in range(BLOCKS):
            block = image[ys[i] : ys[i + 1], xs[j] : xs[j + 1], :3].astype(np.float64)
            out[i, j] = block.reshape(-1, 3).mean(axis=0)
    return out


def check_line(means: np.ndarray, grid: tuple[int, int]) -> str:
    """The comment line holding the check value (``means``: :func:`block_means`)."""
    w, h = grid
    values = " ".join(f"{v:.2f}" for v in np.asarray(means).ravel())
    return f"{CHECK_PREFIX}test still {w}x{h}, {BLOCKS}x{BLOCKS} blocks RGB mean levels {values}"


def parse_check(text: str) -> tuple[tuple[int, int], np.ndarray] | None:
    """The (W, H) grid and (BLOCKS, BLOCKS, 3) levels of a file's check line; None when the
    file has none (exported before viewcomp wrote it).

    Raises:
        ValueError: a check line that does not parse (an edited file).
    """
    line = next((ln for ln in text.splitlines() if ln.startswith(CHECK_PREFIX)), None)
    if line is None:
        return None
    m = re.fullmatch(
        r"test still (\d+)x(\d+), (\d+)x\3 blocks RGB mean levels ([-\d. ]+)",
        line[len(CHECK_PREFIX) :].strip(),
    )
    if m is None or int(m[3]) != BLOCKS:
        raise ValueError(f"the check line does not parse: {line[:80]!r}")
    values = np.array([float(v) for v in m[4].split()])
    if values.size != BLOCKS * BLOCKS * 3:
        raise ValueError(f"the check line has {values.size} values, not {BLOCKS * BLOCKS * 3}")
    return (int(m[1]), int(m[2])), values.reshape(BLOCKS, BLOCKS, 3)


def texture_line(names: list[str]) -> str:
    """The header line listing the file's ``//!TEXTURE`` blocks in order."""
    return f"{LIST_PREFIX}{len(names)}: {' '.join(names)} (the last one's data ends the file)"


def structure_problems(text: str) -> list[str]:
    """What is missing from a shader's text, as phrases ("no //!TEXTURE VC_ROW0", ...);
    empty when every ``//!BIND`` other than mpv's own textures, and every texture of the
    header's list (:func:`texture_line`), has a ``//!TEXTURE`` block whose hex data fills
    its SIZE x FORMAT, and the list's last texture is the file's last block. A file with a
    check line must have the list (a file exported before either has neither)."""
    lines = text.splitlines()
    binds = [ln.split()[1] for ln in lines if ln.startswith("//!BIND ") and len(ln.split()) > 1]
    saved = {ln.split()[1] for ln in lines if ln.startswith("//!SAVE ") and len(ln.split()) > 1}
    found, problems = _textures(lines)
    listed = next((ln for ln in lines if ln.startswith(LIST_PREFIX)), None)
    names = []
    if listed is not None:
        names = listed[len(LIST_PREFIX) :].partition(":")[2].split("(")[0].split()
    elif any(ln.startswith(CHECK_PREFIX) for ln in lines):
        problems.append(f"no line {LIST_PREFIX.strip()!r} in the header")
    for name in dict.fromkeys([*binds, *names]):
        if name not in MPV_TEXTURES and name not in saved and name not in found:
            problems.append(f"no //!TEXTURE {name}")
    blocks = [ln[len("//!TEXTURE") :].strip() for ln in lines if ln.startswith("//!TEXTURE")]
    if names and names[-1] in found and blocks[-1:] != names[-1:]:
        problems.append(f"the file does not end with //!TEXTURE {names[-1]}")
    return problems


def _textures(lines: list[str]) -> tuple[set[str], list[str]]:
    """The names of the complete ``//!TEXTURE`` blocks, and phrases for incomplete ones."""
    found: set[str] = set()
    problems: list[str] = []
    starts = [i for i, ln in enumerate(lines) if ln.startswith("//!TEXTURE")]
    for k, i in enumerate(starts):
        end = starts[k + 1] if k + 1 < len(starts) else len(lines)
        name = lines[i][len("//!TEXTURE") :].strip()
        heads = {}
        j = i + 1
        while j < end and lines[j].startswith("//!"):
            key, _, value = lines[j][3:].partition(" ")
            heads[key] = value.strip()
            j += 1
        data = "".join(ln.strip() for ln in lines[j:end] if not ln.startswith("//"))
        try:
            size = [int(v) for v in heads.get("SIZE", "").split()]
            want = int(np.prod(size)) * _BYTES[heads.get("FORMAT", "")] * 2
        except (KeyError, ValueError):
            problems.append(f"//!TEXTURE {name} without a SIZE and FORMAT viewcomp writes")
            continue
        if len(data) != want or not re.fullmatch(r"[0-9a-fA-F]*", data):
            problems.append(f"//!TEXTURE {name} holds {len(data)} of its {want} hex digits")
            continue
        found.add(name)
    return found, problems
