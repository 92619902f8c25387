// The pixel method's mpv hook of `viewcomp export-mpv` for a fixed eye and tone map: per
// pixel one affine map from the frame's forward-LUT value pw to the inverse LUT's squared
// position, t2 = G pw + w (viewcomp.rt.export.mpv.held_rows: the GL compensator's view cache
// with the tone map folded in), read from VC_ROW0..2 (row i = G_i | w_i) at the output
// pixel and applied as the GL compensator's cached path (METHOD 3 of compensate.frag.glsl).
//
// Defines (literals, besides those of mpv_lut.glsl): VC_S_INIT, VC_O_INIT (vec4[3]: row i =
// VC_S[i] t + VC_O[i] for the texture's value t), VC_SQ_LO, VC_SQ_HI (pixel_t2's clamp),
// VC_SQ_SCALE and VC_SQ_OFF (unused here: folded into the rows); VC_SPLIT 1: VC_ROWi holds
// only the residual of row i over a smooth base VC_BASEi of VC_BASE_SIZE texels
// (viewcomp.rt.export.mpv.split_smooth), which is added back.

#include "mpv_lut.glsl"

const vec4 VC_S[3] = VC_S_INIT;
const vec4 VC_O[3] = VC_O_INIT;

#if VC_SPLIT == 1
// The smooth base at uv, interpolated bilinearly between its texel centres in float (as
// cv2.resize INTER_LINEAR, edges clamped), not by the texture unit, whose weights have
// only 8 fractional bits on many GPUs.
vec4 vc_base(sampler2D base, vec2 uv) {
    vec2 p = uv * VC_BASE_SIZE - 0.5;
    vec2 i = floor(p);
    vec2 f = p - i;
    vec2 lo = (clamp(i, vec2(0.0), VC_BASE_SIZE - 1.0) + 0.5) / VC_BASE_SIZE;
    vec2 hi = (clamp(i + 1.0, vec2(0.0), VC_BASE_SIZE - 1.0) + 0.5) / VC_BASE_SIZE;
    vec4 a = mix(texture(base, lo), texture(base, vec2(hi.x, lo.y)), f.x);
    vec4 b = mix(texture(base, vec2(lo.x, hi.y)), texture(base, hi), f.x);
    return mix(a, b, f.y);
}
#define VC_ADD_BASE(base, uv) + vc_base(base, uv)
#else
#define VC_ADD_BASE(base, uv)
#endif

vec4 hook() {
    vec4 src = HOOKED_tex(HOOKED_pos);
    vec2 uv = vc_map_pos();
    vec4 r0 = texture(VC_ROW0, uv) * VC_S[0] + VC_O[0] VC_ADD_BASE(VC_BASE0, uv);
    vec4 r1 = texture(VC_ROW1, uv) * VC_S[1] + VC_O[1] VC_ADD_BASE(VC_BASE1, uv);
    vec4 r2 = texture(VC_ROW2, uv) * VC_S[2] + VC_O[2] VC_ADD_BASE(VC_BASE2, uv);
    vec3 t2 = cached_t2(r0, r1, r2, vec3(0.0), vec3(0.0), vc_forward(src.rgb * 255.0), 1.0, 0.0);
    return vec4(quantise(lut_inverse_sq(clamp(t2, VC_SQ_LO, VC_SQ_HI))), src.a);
}
