// The pixel method's mpv hook of `viewcomp export-mpv` for a fixed eye and tone map: per
// pixel one affine map from the frame's forward-LUT value pw to the inverse LUT's squared
// position, t2 = G pw + w (viewcomp.rt.export.mpv.held_rows: the GL compensator's view cache
// with the tone map folded in), read from VC_ROW0..2 (row i = G_i | w_i) at the output
// pixel and applied as the GL compensator's cached path (METHOD 3 of compensate.frag.glsl).
//
// Defines (literals, besides those of mpv_lut.glsl): VC_S_INIT, VC_O_INIT (vec4[3]: row i =
// VC_S[i] t + VC_O[i] for the texture's value t), VC_SQ_LO, VC_SQ_HI (pixel_t2's clamp),
// VC_SQ_SCALE and VC_SQ_OFF (unused here: folded into the rows).

#include "mpv_lut.glsl"

const vec4 VC_S[3] = VC_S_INIT;
const vec4 VC_O[3] = VC_O_INIT;

vec4 hook() {
    vec4 src = HOOKED_tex(HOOKED_pos);
    vec2 uv = vc_map_pos();
    vec4 r0 = texture(VC_ROW0, uv) * VC_S[0] + VC_O[0];
    vec4 r1 = texture(VC_ROW1, uv) * VC_S[1] + VC_O[1];
    vec4 r2 = texture(VC_ROW2, uv) * VC_S[2] + VC_O[2];
    vec3 t2 = cached_t2(r0, r1, r2, vec3(0.0), vec3(0.0), vc_forward(src.rgb * 255.0), 1.0, 0.0);
    return vec4(quantise(lut_inverse_sq(clamp(t2, VC_SQ_LO, VC_SQ_HI))), src.a);
}
