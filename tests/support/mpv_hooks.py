"""Reading an exported mpv user shader (`viewcomp export-mpv`) in tests: its sections as mpv
splits them, its textures decoded, and its hook run by this project's GL path
(shaders/mpv_harness.frag.glsl) at the grid's size."""

from __future__ import annotations

import re
from typing import Any

import numpy as np

from viewcomp.shaders import build_program, load


def sections(text: str) -> list[tuple[dict[str, list[str]], str]]:
    """Split a user shader into (directives, body) blocks, as mpv does (at every "//!")."""
    first = text.index("//!")
    blocks = []
    for chunk in re.split(r"(?=^//!(?:HOOK|TEXTURE|PARAM)\b)", text[first:], flags=re.M):
        if not chunk.strip():
            continue
        heads: dict[str, list[str]] = {}
        lines = chunk.split("\n")
        i = 0
        while i < len(lines) and lines[i].startswith("//!"):
            key, _, value = lines[i][3:].partition(" ")
            heads.setdefault(key, []).append(value)
            i += 1
        blocks.append((heads, "\n".join(lines[i:])))
    return blocks


def textures(text: str) -> dict[str, np.ndarray]:
    """Every //!TEXTURE decoded to (H, W, 4) (uint8 for rgba8, uint16 for rgba16, float32
    for rgba32f)."""
    out = {}
    for heads, body in sections(text):
        if "TEXTURE" not in heads:
            continue
        w, h = (int(v) for v in heads["SIZE"][0].split())
        dtype = {"rgba8": "u1", "rgba16": "<u2", "rgba32f": "<f4"}[heads["FORMAT"][0]]
        data = np.frombuffer(bytes.fromhex(body.strip()), dtype)
        assert data.size == w * h * 4, heads["TEXTURE"]
        out[heads["TEXTURE"][0]] = data.reshape(h, w, 4)
    return out


def run_hook(ctx: Any, text: str, frame: np.ndarray, angle: float = 90.0) -> np.ndarray:
    """The exported hook's GLSL itself, run by this project's GL path at the grid's size.

    shaders/mpv_harness.frag.glsl gives it what mpv would (HOOKED_pos, HOOKED_tex, the
    //!TEXTURE sections as NEAREST textures, the parameter ``angle``); returns the output
    levels (H, W, 3) uint8, row 0 = the frame's row 0.
    """
    import moderngl

    body = next(b for heads, b in sections(text) if "HOOK" in heads)
    prog = build_program(ctx, fragment="mpv_harness.frag.glsl",
                         loader=lambda n: body if n == "mpv_export.glsl" else load(n))  # fmt: skip
    h, w = frame.shape[:2]
    objects: list[Any] = [prog]
    try:
        rgba = np.dstack([frame, np.full((h, w), 255, np.uint8)])
        images = {"HOOKED_raw": rgba, **textures(text)}
        for unit, (name, img) in enumerate(images.items()):
            dtype = {np.dtype(np.uint8): "f1", np.dtype("<u2"): "nu2"}.get(img.dtype, "f4")
            tex = ctx.texture((img.shape[1], img.shape[0]), 4, np.ascontiguousarray(img),
                              dtype=dtype)  # fmt: skip
            objects.append(tex)
            tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
            tex.use(unit)
            if name in prog:
                prog[name].value = unit
        if "angle" in prog:
            prog["angle"].value = angle
        if "u_flip_y" in prog:
            prog["u_flip_y"].value = 0
        color = ctx.renderbuffer((w, h), 4)  # released below: the session context is shared
        fbo = ctx.framebuffer(color_attachments=[color])
        vao = ctx.vertex_array(prog, [])
        objects += [color, fbo, vao]
        fbo.use()
        vao.render(moderngl.TRIANGLES, vertices=3)
        return np.frombuffer(fbo.read(components=3, alignment=1), np.uint8).reshape(h, w, 3)
    finally:
        # the default framebuffer first, as Compensator.release does: moderngl re-binds its
        # current framebuffer after making the next one, and a deleted name there is a GL
        # error in whatever test uses the shared context next
        (ctx.screen or ctx.detect_framebuffer(0)).use()
        for obj in reversed(objects):
            obj.release()
