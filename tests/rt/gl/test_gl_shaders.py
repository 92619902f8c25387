"""Every shader compiles; a compile error names the .glsl file, the stage and the line."""

from __future__ import annotations

import re

import pytest

from viewcomp.shaders import ShaderError, assemble, build_program, list_shaders, load

pytestmark = pytest.mark.gl

VARIANTS = [(m, i) for m in (0, 1, 2, 3, 4) for i in (0, 1)]


def test_shaders_are_package_data() -> None:
    names = list_shaders()
    assert {"fullscreen.vert.glsl", "compensate.frag.glsl", "yuv.glsl"} <= set(names)
    assert load("yuv.glsl") is load("yuv.glsl")  # cached


def test_unknown_shader_is_a_clear_error() -> None:
    with pytest.raises(ShaderError, match=r"no shader file 'nope\.glsl'"):
        load("nope.glsl")


def test_line_directives_keep_file_line_numbers() -> None:
    asm = assemble("compensate.frag.glsl", {"METHOD": 1})
    assert asm.files == ("compensate.frag.glsl", "yuv.glsl", "compensate_core.glsl")
    lines = asm.source.splitlines()
    assert lines[0].startswith("#version 330")
    # The line after "#line 1 1" is yuv.glsl's first line.
    i = lines.index("#line 1 1")
    assert lines[i + 1] == load("yuv.glsl").splitlines()[0]


@pytest.mark.parametrize(("method", "inp"), VARIANTS)
def test_every_variant_compiles(gl_ctx, method: int, inp: int) -> None:
    """With the file's defaults (Compensator compiles its constants in as literals)."""
    prog = build_program(gl_ctx, defines={"METHOD": method, "INPUT": inp})
    # Per frame the fragment shader reads no uniforms (llvmpipe pays per pixel for them):
    # everything but the samplers lives in the vertex shader.
    names = [n for n in prog if not n.startswith(("u_", "gl_")) or n in ("u_frame", "u_flip_y")]
    assert all(n in ("u_frame", "u_flip_y") for n in names), names
    prog.release()


def _broken_loader(target: str, line: int):
    def loader(name: str) -> str:
        text = load(name)
        if name != target:
            return text
        lines = text.splitlines()
        lines.insert(line - 1, "this is not GLSL;")
        return "\n".join(lines) + "\n"

    return loader


@pytest.mark.parametrize(
    ("target", "line", "stage"),
    [
        ("compensate.frag.glsl", 60, "fragment"),
        ("yuv.glsl", 20, "fragment"),
        ("compensate_core.glsl", 20, "fragment"),
        ("fullscreen.vert.glsl", 5, "vertex"),
    ],
)
def test_syntax_error_names_file_stage_and_line(gl_ctx, target: str, line: int, stage: str):
    with pytest.raises(ShaderError) as info:
        build_program(gl_ctx, loader=_broken_loader(target, line))
    msg = str(info.value)
    assert msg.startswith(f"{stage} shader {target}:{line}"), msg
    assert re.search(rf"{re.escape(target)}:{line}:\d+: error", msg), msg
