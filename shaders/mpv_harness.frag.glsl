#version 330 core
// Runs the body of an exported mpv user shader (`viewcomp export-mpv`, its HOOK section,
// included as "mpv_export.glsl" by the caller's loader) as a fragment shader of this
// project's GL path, with what mpv provides around it: HOOKED_pos (the texture coordinate of
// this fragment's grid pixel, from fullscreen.vert.glsl), HOOKED_size (the frame's size),
// HOOKED_tex (the frame,
// normalised), every TEXTURE section as a sampler of its name and the PARAM angle as a
// uniform. The output is hook() at the grid's size: what mpv shows fullscreen on the
// projector whose grid was calibrated.

in vec2 v_uv;
out vec4 frag_color;

uniform sampler2D HOOKED_raw;
uniform sampler2D VC_MAP0;
uniform sampler2D VC_MAP1;
uniform sampler2D VC_MAP2;
uniform sampler2D VC_MAP3;
uniform sampler2D VC_MAP4;
uniform sampler2D VC_MAP5;
uniform sampler2D VC_MAP6;
uniform sampler2D VC_MAP7;
uniform sampler2D VC_ROW0;
uniform sampler2D VC_ROW1;
uniform sampler2D VC_ROW2;
uniform sampler2D VC_ROW3;
uniform sampler2D VC_ROW4;
uniform sampler2D VC_ROW5;
uniform sampler2D VC_BASE0;
uniform sampler2D VC_BASE1;
uniform sampler2D VC_BASE2;
uniform sampler2D VC_LUT;
uniform float angle;

#define HOOKED_pos v_uv
#define HOOKED_tex(pos) texture(HOOKED_raw, pos)
#define HOOKED_size vec2(textureSize(HOOKED_raw, 0))

#include "mpv_export.glsl"

void main() {
    frag_color = hook();
}
