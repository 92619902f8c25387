"""GLSL 330 core shaders of viewcomp, shipped as package data, and their loader.

Every shader is a real ``.glsl`` file in this package. :func:`load` reads one (cached);
:func:`assemble` expands ``#include "other.glsl"`` lines and inserts ``#line L S`` directives
so that the driver's line numbers equal the file's and its source-string number ``S`` names
the file; :func:`build_program` compiles a program and, on failure, raises
:class:`ShaderError` naming the ``.glsl`` file, the stage and the line.

Files:

- ``fullscreen.vert.glsl``: a fullscreen triangle from ``gl_VertexID`` (no vertex buffer).
- ``yuv.glsl``: yuv420p planes (Y R8UI, UV RG8UI) -> RGB 8-bit levels, fixed point, bit-exact
  with :func:`viewcomp.rt.media.frames.yuv420p_to_rgb` (included by the fragment shader).
- ``compensate_core.glsl``: the per-pixel formula of docs/RUNTIME.md as functions of values
  already fetched (the one GLSL source of it), included by the next two.
- ``compensate.frag.glsl``: the GL compensator's fragment shader for the methods
  ``identity``, ``pixel`` and ``paper``, one fragment path per variant.
- ``mpv_held.glsl`` (pixel method, a fixed eye), ``mpv_pixel.glsl`` (pixel method, the
  eye from a ``//!PARAM``), ``mpv_adaptive.glsl`` (pixel method, a fixed eye, the adaptive
  tone map), ``mpv_paper.glsl``: the body of the mpv user shader of
  ``viewcomp export-mpv`` (mpv's sampling of the frame and the maps around the same
  formula), all including ``mpv_lut.glsl`` (the formula and mpv's sampling of the LUTs).
- ``mpv_harness.frag.glsl``: runs an exported mpv hook body as a fragment shader here (for
  the tests: what mpv would run, against the numpy reference).
- ``present.frag.glsl``: an image texture over the viewport.

:func:`literal`, :func:`vec_literal` and :func:`array_literal` print numbers as GLSL
literals that read back as the same float32 (the ``#define`` values of both hosts).
"""

from __future__ import annotations

import functools
import importlib.resources
import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from viewcomp.calib.errors import ShaderError

if TYPE_CHECKING:
    import moderngl

__all__ = [
    "ShaderError",
    "array_literal",
    "assemble",
    "build_program",
    "list_shaders",
    "literal",
    "load",
    "vec_literal",
]

_INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"\s*$')
_VERSION = re.compile(r"^\s*#\s*version\b")
# Mesa: "1:4(1): error: ..."; NVIDIA: "1(4) : error ..."; both carry source and line.
_MESA_LOC = re.compile(r"^(\d+):(\d+)\((\d+)\):\s*(.*)$")
_NV_LOC = re.compile(r"^(\d+)\((\d+)\)\s*:\s*(.*)$")


def list_shaders() -> list[str]:
    """Names of every ``.glsl`` file shipped in this package, sorted."""
    root = importlib.resources.files(__package__)
    return sorted(p.name for p in root.iterdir() if p.name.endswith(".glsl"))


@functools.cache
def load(name: str) -> str:
    """The text of the package's shader file ``name`` (e.g. ``"yuv.glsl"``), cached.

    Raises:
        ShaderError: no such file in the package.
    """
    res = importlib.resources.files(__package__).joinpath(name)
    if not name.endswith(".glsl") or not res.is_file():
        raise ShaderError(f"no shader file {name!r} in viewcomp.shaders (have {list_shaders()})")
    return res.read_text(encoding="utf-8")


@dataclass(frozen=True)
class Assembled:
    """A shader source ready for the driver and the file of each GLSL source-string number.

    ``files[s]`` is the ``.glsl`` file name that ``#line L s`` directives refer to.
    """

    source: str
    files: tuple[str, ...]


def assemble(
    name: str,
    defines: dict[str, str | int | float] | None = None,
    loader: Callable[[str], str] = load,
    *,
    directives: bool = True,
) -> Assembled:
    """Expand includes of shader ``name`` and insert ``#line`` directives.

    The first line of ``name`` must be ``#version ...``; ``defines`` become ``#define`` lines
    after it. Included files must not carry a ``#version`` and are expanded once each.
    ``loader`` maps a file name to its text (the package's :func:`load` by default).
    ``directives=False``: a fragment of a shader for another program (an mpv hook body): no
    ``#version`` line (the ``#define`` lines come first) and no ``#line`` directives.
    """
    files: list[str] = []
    out: list[str] = []
    seen: set[str] = set()

    def expand(fname: str, top: bool) -> None:
        idx = len(files)
        files.append(fname)
        lines = loader(fname).splitlines()
        start = 0
        if top and directives:
            if not lines or not _VERSION.match(lines[0]):
                raise ShaderError(f"{fname}:1: the first line must be a #version directive")
            out.append(lines[0])
            start = 1
        if top:
            for key, val in (defines or {}).items():
                out.append(f"#define {key} {val}")
        if directives:
            out.append(f"#line {start + 1} {idx}")
        for i in range(start, len(lines)):
            line = lines[i]
            m = _INCLUDE.match(line)
            if m:
                inc = m.group(1)
                if inc not in seen:
                    seen.add(inc)
                    expand(inc, top=False)
                if directives:
                    out.append(f"#line {i + 2} {idx}")
                continue
            if _VERSION.match(line):
                raise ShaderError(f"{fname}:{i + 1}: #version is only allowed on line 1")
            out.append(line)

    seen.add(name)
    expand(name, top=True)
    return Assembled("\n".join(out) + "\n", tuple(files))


def literal(x: float) -> str:
    """A float32 value as a GLSL float literal that parses back to the same float32.

    Raises:
        ValueError: ``x`` is not finite (no GLSL literal for it).
    """
    v = float(np.float32(x))
    if not math.isfinite(v):
        raise ValueError(f"cannot write the non-finite value {x!r} as a GLSL literal")
    text = f"{v:.9g}"
    return text if any(c in text for c in ".en") else text + ".0"


def vec_literal(values: Any) -> str:
    """``vecN(..)`` of N = 2..4 numbers (any array-like, flattened)."""
    vals = [literal(v) for v in np.asarray(values, np.float64).ravel()]
    return f"vec{len(vals)}({', '.join(vals)})"


def array_literal(kind: str, items: list[str]) -> str:
    """A GLSL array constructor ``kind[n](items...)`` of literals already printed."""
    return f"{kind}[{len(items)}]({', '.join(items)})"


def _map_log(log: str, files: tuple[str, ...]) -> tuple[str, int | None, str]:
    """Rewrite driver locations ``S:L(C)`` in ``log`` as ``file:L:C``; first file/line found."""
    first_file, first_line = "", None
    mapped = []
    for raw in log.splitlines():
        line = raw.strip()
        m = _MESA_LOC.match(line)
        src = ln = col = None
        rest = line
        if m:
            src, ln, col, rest = int(m.group(1)), int(m.group(2)), int(m.group(3)), m.group(4)
        else:
            m = _NV_LOC.match(line)
            if m:
                src, ln, rest = int(m.group(1)), int(m.group(2)), m.group(3)
        if src is not None and ln is not None:
            fname = files[src] if 0 <= src < len(files) else f"<source {src}>"
            loc = f"{fname}:{ln}" + (f":{col}" if col is not None else "")
            if first_line is None:
                first_file, first_line = fname, ln
            mapped.append(f"{loc}: {rest}")
        elif line:
            mapped.append(line)
    return first_file, first_line, "\n".join(mapped)


def build_program(
    ctx: moderngl.Context,
    vertex: str = "fullscreen.vert.glsl",
    fragment: str = "compensate.frag.glsl",
    defines: dict[str, str | int | float] | None = None,
    loader: Callable[[str], str] = load,
) -> moderngl.Program:
    """Compile and link a program from the package's shader files.

    Each stage is compiled from its assembled source; on failure the :class:`ShaderError`
    reads e.g. ``fragment shader compensate.frag.glsl:42: error: syntax error ...``.
    """
    import moderngl

    stages = {
        "vertex": assemble(vertex, defines, loader),
        "fragment": assemble(fragment, defines, loader),
    }
    try:
        return ctx.program(
            vertex_shader=stages["vertex"].source, fragment_shader=stages["fragment"].source
        )
    except moderngl.Error as exc:
        text = str(exc)
        stage = "fragment" if "fragment_shader" in text else "vertex"
        if "Linker failed" in text:
            raise ShaderError(
                f"linking {vertex} + {fragment} failed:\n{_strip_header(text)}"
            ) from exc
        fname, line, mapped = _map_log(_strip_header(text), stages[stage].files)
        where = (
            f"{fname}:{line}" if line is not None else (vertex if stage == "vertex" else fragment)
        )
        raise ShaderError(f"{stage} shader {where}: compile failed\n{mapped}") from exc


def _strip_header(text: str) -> str:
    """Drop moderngl's banner lines ("GLSL Compiler failed", "fragment_shader", "====")."""
    keep = []
    for line in text.splitlines():
        s = line.strip()
        if not s or s.startswith("GLSL ") or set(s) == {"="}:
            continue
        if s in ("vertex_shader", "fragment_shader", "geometry_shader", "Program"):
            continue
        keep.append(s)
    return "\n".join(keep)
