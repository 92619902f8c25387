// The pixel method's mpv hook of `viewcomp export-mpv --tone adaptive` for a fixed eye: the
// adaptive tone map (compensate_core.glsl's soft_light, as METHOD 7 of compensate.frag.glsl)
// with one field per export. Per pixel six texels VC_ROW0..5 (viewcomp.rt.export.mpv_adaptive
// .adaptive_texels): rows i of G | a (u = G pw + a = M^-1 C_w), (v, 0), (c, 0) and the white
// screen's luminance row (k^T Ww | k . Aw).
//
// Defines (literals, besides those of mpv_lut.glsl): VC_S_INIT, VC_O_INIT (vec4[6]: texel k =
// VC_S[k] t + VC_O[k] for the texture's value t); VC_SQ_SCALE, VC_SQ_OFF, VC_SQ_LO, VC_SQ_HI
// (pixel_t2); VC_FIELD_NX, VC_FIELD_NY, VC_FIELD_STEP, VC_FIELD_INIT (the field's nodes
// (gain, offset), row-major), VC_FIELD_HUE (its hue weight), VC_GAMUT_K, VC_GAMUT_LIMIT
// (soft_light's constants).

#include "mpv_lut.glsl"

const vec4 VC_S[6] = VC_S_INIT;
const vec4 VC_O[6] = VC_O_INIT;
const vec2 VC_FIELD[VC_FIELD_NX * VC_FIELD_NY] = VC_FIELD_INIT;

vec4 hook() {
    vec4 src = HOOKED_tex(HOOKED_pos);
    vec2 uv = vc_map_pos();
    vec4 r0 = texture(VC_ROW0, uv) * VC_S[0] + VC_O[0];
    vec4 r1 = texture(VC_ROW1, uv) * VC_S[1] + VC_O[1];
    vec4 r2 = texture(VC_ROW2, uv) * VC_S[2] + VC_O[2];
    vec3 v = (texture(VC_ROW3, uv) * VC_S[3] + VC_O[3]).xyz;
    vec3 c = (texture(VC_ROW4, uv) * VC_S[4] + VC_O[4]).xyz;
    vec4 lr = texture(VC_ROW5, uv) * VC_S[5] + VC_O[5];
    vec3 pw = vc_forward(src.rgb * 255.0);
    vec3 u = vec3(dot(r0.xyz, pw), dot(r1.xyz, pw), dot(r2.xyz, pw)) + vec3(r0.w, r1.w, r2.w);
    vec2 f;
    ivec4 i = field_cell(ivec2(uv * VC_GRID), VC_FIELD_NX, VC_FIELD_NY, VC_FIELD_STEP, f);
    vec2 go = field_blend(VC_FIELD[i.x], VC_FIELD[i.y], VC_FIELD[i.z], VC_FIELD[i.w], f);
    vec3 y = soft_light(u, v, c, dot(lr.xyz, pw) + lr.w, go,
                        grey_range(v, c, VC_GAMUT_K.y, VC_GAMUT_LIMIT), VC_GAMUT_K, vec3(1.0),
                        VC_FIELD_HUE);
    vec3 t2 = pixel_t2(y, VC_SQ_SCALE, VC_SQ_OFF, VC_SQ_LO, VC_SQ_HI);
    return vec4(quantise(lut_inverse_sq(t2)), src.a);
}
