// The pixel method's eye-following mpv hook of `viewcomp export-mpv --param`: the maps
// VC_MAP0..7 (texel k of viewcomp.calib.model.shader_inputs.pixel_texels in VC_MAPk) sampled at the
// output pixel, solved for the eye as the GL compensator's compensate.frag.glsl does. (A
// fixed eye: mpv_held.glsl.)
//
// Defines (literals, besides those of mpv_lut.glsl): VC_S_INIT, VC_O_INIT (vec4[8]: texel k
// of the maps = VC_S[k] t + VC_O[k] for the texture's value t), VC_LOBE_HALF (true: the
// half-vector angle), VC_LOBE_N (the lobe table's entries, row 2 of VC_LUT), VC_LOBE_BLACK
// (the projector leak's share of the black level), VC_SQ_SCALE,
// VC_SQ_OFF, VC_SQ_LO, VC_SQ_HI (pixel_t2). The eye and the tone map follow the parameter
// angle (degrees; mpv's PARAM), clamped to [VC_ANGLE_MIN, VC_ANGLE_MAX] (the limits of
// viewcomp.calib.world.eye, whose eye_from_angle is the formula here), the eye at
// (VC_DIST cos, VC_HEIGHT, VC_DIST sin) and the tone map interpolated in a table of
// VC_TONE_N entries from VC_TONE_FIRST degrees every VC_TONE_STEP (VC_TONE_ALPHA_INIT,
// VC_TONE_BETA_INIT).

#include "mpv_lut.glsl"

const vec4 VC_S[8] = VC_S_INIT;
const vec4 VC_O[8] = VC_O_INIT;

const float VC_TONE_ALPHA[VC_TONE_N] = VC_TONE_ALPHA_INIT;
const float VC_TONE_BETA[VC_TONE_N] = VC_TONE_BETA_INIT;

vec3 vc_eye() {
    float t = radians(clamp(angle, VC_ANGLE_MIN, VC_ANGLE_MAX));
    return vec3(VC_DIST * cos(t), VC_HEIGHT, VC_DIST * sin(t));
}

vec2 vc_tone() {
    float x = clamp((angle - VC_TONE_FIRST) / VC_TONE_STEP, 0.0, float(VC_TONE_N - 1));
    int i = min(int(floor(x)), VC_TONE_N - 2);
    float f = x - float(i);
    return vec2(mix(VC_TONE_ALPHA[i], VC_TONE_ALPHA[i + 1], f),
                mix(VC_TONE_BETA[i], VC_TONE_BETA[i + 1], f));
}

vec4 hook() {
    vec4 src = HOOKED_tex(HOOKED_pos);
    vec2 uv = vc_map_pos();
    PixelMaps m = pixel_maps(
        texture(VC_MAP0, uv) * VC_S[0] + VC_O[0], texture(VC_MAP1, uv) * VC_S[1] + VC_O[1],
        texture(VC_MAP2, uv) * VC_S[2] + VC_O[2], texture(VC_MAP3, uv) * VC_S[3] + VC_O[3],
        texture(VC_MAP4, uv) * VC_S[4] + VC_O[4], texture(VC_MAP5, uv) * VC_S[5] + VC_O[5],
        texture(VC_MAP6, uv) * VC_S[6] + VC_O[6], texture(VC_MAP7, uv) * VC_S[7] + VC_O[7]);
    vec2 tone = vc_tone();
    vec3 y = solve_pixel(m, vc_forward(src.rgb * 255.0), vc_eye(), tone.x, tone.y,
                         VC_LOBE_HALF, VC_LOBE_N, VC_LOBE_BLACK);
    vec3 t2 = pixel_t2(y, VC_SQ_SCALE, VC_SQ_OFF, VC_SQ_LO, VC_SQ_HI);
    return vec4(quantise(lut_inverse_sq(t2)), src.a);
}
