#version 330 core
// The per-frame formula of docs/RUNTIME.md, one fragment path for the methods identity (0),
// pixel (1) and paper (2); the numpy reference is viewcomp.calib.reference.compensate.
//
// Addressing: the fragment at window pixel (x, y) - u_origin reads texel (x, y) of every
// per-pixel texture, i.e. array row y; read-back of rows 0.. gives array rows 0.. again, so
// nothing is flipped. u_flip_y = 1 reads row (u_size.y - 1 - y) instead, for a host's
// default framebuffer where window y = 0 is the bottom of the screen.
//
// Output: level = roundEven(255 * clamp(out, 0, 1)) (= np.rint), written as level / 255 so
// that any float -> unorm8 conversion of the framebuffer returns exactly that level.

#include "yuv.glsl"

// Compiled once per (METHOD, INPUT) from this one source (llvmpipe would otherwise run
// every branch for every pixel): METHOD 0 identity, 1 pixel, 2 paper; INPUT 0 the RGB8UI
// texture u_rgb, 1 yuv420p planes (yuv.glsl).
#ifndef METHOD
#define METHOD 1
#endif
#ifndef INPUT
#define INPUT 0
#endif
uniform ivec2 u_origin;       // window pixel of texel (0, 0)
uniform ivec2 u_size;         // (W, H) of the projector grid
uniform int u_flip_y;

uniform usampler2D u_rgb;     // frame, 8-bit levels

uniform sampler2D u_fwd;      // 256 x 1 RGBA32F: level -> linear (fwd_lut, interpolated)
uniform sampler2D u_inv;      // N x 3 RG32F: inv_lut on [u_inv_lo, u_inv_hi] -> 0..1
uniform vec3 u_inv_lo;
uniform vec3 u_inv_hi;

uniform float u_alpha;        // tone map T = alpha * Cw + beta
uniform float u_beta;
uniform vec3 u_eye;           // metres, world

// pixel method: RGBA32F textures, row i of Ww (xyz) and Aw[i] (w); same for Wc / Ac.
uniform sampler2D u_w0;
uniform sampler2D u_w1;
uniform sampler2D u_w2;
uniform sampler2D u_c0;
uniform sampler2D u_c1;
uniform sampler2D u_c2;
uniform sampler2D u_refl;     // RGBA32F unit reflection vectors (xyz)
uniform sampler2D u_pos;      // RGBA32F surface points (xyz, metres) and the camera's lobe
                              // (w) = max(dot(refl, normalize(cam_eye - pos)), 0)^gamma
uniform vec3 u_kappa;
uniform float u_gamma;

// paper method: global matrices.
uniform mat3 u_Ww;
uniform mat3 u_Wc_inv;

out vec4 frag_color;

// Forward LUT at integer levels. u_fwd holds reference.lut_forward(fwd_lut, level) for
// every level 0..255, computed by numpy, so this is bit-identical to the reference.
vec3 lut_forward(ivec3 level) {
    return vec3(texelFetch(u_fwd, ivec2(level.r, 0), 0).r,
                texelFetch(u_fwd, ivec2(level.g, 0), 0).g,
                texelFetch(u_fwd, ivec2(level.b, 0), 0).b);
}

// Linear interpolation in the inverse LUT (reference.lut_inverse); returns 0..1.
// u_inv is N x 3 RG32F: texel (i, c) = (inv_lut[i, c], inv_lut[i + 1, c]), one fetch for
// both ends of the interval.
vec3 lut_inverse(vec3 y) {
    int n = textureSize(u_inv, 0).x;
    vec3 span = max(u_inv_hi - u_inv_lo, vec3(1e-12));
    vec3 t = clamp((y - u_inv_lo) / span, 0.0, 1.0) * float(n - 1);
    ivec3 i0 = min(ivec3(floor(t)), ivec3(n - 2));
    vec3 f = t - vec3(i0);
    vec2 ab0 = texelFetch(u_inv, ivec2(i0.x, 0), 0).xy;
    vec2 ab1 = texelFetch(u_inv, ivec2(i0.y, 1), 0).xy;
    vec2 ab2 = texelFetch(u_inv, ivec2(i0.z, 2), 0).xy;
    vec3 a = vec3(ab0.x, ab1.x, ab2.x);
    vec3 b = vec3(ab0.y, ab1.y, ab2.y);
    return a + (b - a) * f;
}

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy) - u_origin;
    if (u_flip_y != 0) {
        p.y = u_size.y - 1 - p.y;
    }
#if INPUT == 1
    ivec3 level = yuv420p_levels(p);
#else
    ivec3 level = ivec3(texelFetch(u_rgb, p, 0).rgb);
#endif

    vec3 result;
#if METHOD == 1
    {
        vec4 w0 = texelFetch(u_w0, p, 0);
        vec4 w1 = texelFetch(u_w1, p, 0);
        vec4 w2 = texelFetch(u_w2, p, 0);
        vec4 c0 = texelFetch(u_c0, p, 0);
        vec4 c1 = texelFetch(u_c1, p, 0);
        vec4 c2 = texelFetch(u_c2, p, 0);
        vec3 refl = texelFetch(u_refl, p, 0).xyz;
        vec4 pos = texelFetch(u_pos, p, 0);

        vec3 pw = lut_forward(level);
        vec3 cw = vec3(dot(w0.xyz, pw), dot(w1.xyz, pw), dot(w2.xyz, pw)) + vec3(w0.w, w1.w, w2.w);
        vec3 target = u_alpha * cw + u_beta;
        float lobe_eye = pow(max(dot(refl, normalize(u_eye - pos.xyz)), 0.0), u_gamma);
        vec3 ds = u_kappa * (lobe_eye - pos.w);
        // Rows of M = Wc + diag(ds) Ww; solve M y = target - Ac by the adjugate.
        vec3 r0 = c0.xyz + ds.x * w0.xyz;
        vec3 r1 = c1.xyz + ds.y * w1.xyz;
        vec3 r2 = c2.xyz + ds.z * w2.xyz;
        vec3 b = target - vec3(c0.w, c1.w, c2.w);
        vec3 k0 = cross(r1, r2);
        float det = dot(r0, k0);
        vec3 y = (k0 * b.x + cross(r2, r0) * b.y + cross(r0, r1) * b.z) / det;
        result = lut_inverse(clamp(y, 0.0, 1.0));
    }
#elif METHOD == 2
    {
        vec3 cw = u_Ww * lut_forward(level);
        vec3 target = u_alpha * cw + u_beta;
        result = lut_inverse(u_Wc_inv * target);
    }
#else
        result = vec3(level) / 255.0;
#endif
    vec3 out_level = roundEven(clamp(result, 0.0, 1.0) * 255.0);
    frag_color = vec4(out_level / 255.0, 1.0);
}
