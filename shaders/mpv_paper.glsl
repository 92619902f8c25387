// The paper method's mpv hook of `viewcomp export-mpv`: global matrices, the eye and the
// tone map folded in on the CPU as for the GL compensator.
//
// Defines (literals, besides those of mpv_lut.glsl): VC_A0, VC_A1, VC_A2, the rows of
// paper_t2 (viewcomp.calib.model.shader_inputs.paper_rows).

#include "mpv_lut.glsl"

vec4 hook() {
    vec4 src = HOOKED_tex(HOOKED_pos);
    float top = float((VC_N_INV - 1) * (VC_N_INV - 1));
    vec3 t2 = paper_t2(VC_A0, VC_A1, VC_A2, vc_forward(src.rgb * 255.0), top);
    return vec4(quantise(lut_inverse_sq(t2)), src.a);
}
