#version 330 core
// The per-frame formula of docs/RUNTIME.md, one fragment path for the methods identity (0),
// pixel (1) and paper (2); the numpy reference is viewcomp.calib.reference.compensate.
//
// Addressing: v_uv (fullscreen.vert.glsl) is the centre of the grid texel this fragment
// computes, row 0 = array row 0, so read-back of rows 0.. gives array rows 0.. again; the
// viewport places the grid and the vertex shader flips it for a window if asked.
//
// Speed on Mesa llvmpipe (docs/BENCHMARKS.md), which the layout follows:
// - Every texture read is textureLod(.., 0) with NEAREST at a texel centre (~1.5x cheaper
//   than texelFetch there).
// - No uniforms: llvmpipe pays per pixel for every uniform component a fragment shader
//   reads. What is fixed for a Compensator (grid size, LUT domain, lobe, the packed maps'
//   scales) is compiled in as #define literals; what changes per frame (eye, tone map, the
//   paper method's matrices) comes from the vertex shader as flat inputs v_frame[].
// - The pixel method's 31 per-pixel values are float32 (8 RGBA32F reads) or, opt-in, 20-bit
//   fixed point in 5 RGBA32UI texels (5 reads, 80 instead of 128 bytes; see Compensator).
//
// Output: level = roundEven(255 * clamp(out, 0, 1)) (= np.rint), written as level / 255 so
// that any float -> unorm8 conversion of the framebuffer returns exactly that level.

// Variant (one program each; llvmpipe would otherwise run every branch for every pixel):
// METHOD 0 identity, 1 pixel, 2 paper; INPUT 0 the RGB8UI texture u_rgb, 1 yuv420p planes
// (yuv.glsl); PACKED 1 the 20-bit maps u_m0..u_m4, 0 the float32 maps u_w0..u_pos.
#ifndef METHOD
#define METHOD 1
#endif
#ifndef INPUT
#define INPUT 0
#endif
#ifndef PACKED
#define PACKED 0
#endif
// Constants of one Compensator (the defaults only let the file compile on its own).
#ifndef GRID_W
#define GRID_W 2
#endif
#ifndef GRID_H
#define GRID_H 2
#endif
#ifndef N_INV
#define N_INV 2
#endif
#ifndef INV_LO
#define INV_LO vec3(0.0)
#endif
#ifndef INV_SCALE
#define INV_SCALE vec3(1.0)
#endif
#ifndef KAPPA
#define KAPPA vec3(0.0)
#endif
#ifndef GAMMA
#define GAMMA 1.0
#endif

#include "yuv.glsl"

in vec2 v_uv;
// Per frame. pixel: [0] = (eye.xyz metres, alpha), [1].x = beta. paper: row i of
// A = diag(s) alpha Wc_inv Ww in [i].xyz and c_i in [i].w, with s = (N - 1) / (hi - lo) and
// c = s (beta Wc_inv 1 - lo): the inverse LUT's position is A fwd(I) + c (folded on the CPU).
flat in vec4 v_frame[4];

uniform usampler2D u_rgb;     // frame, 8-bit levels (RGB8UI)
uniform sampler2D u_fwd;      // 256 x 3 R32F: row c = fwd_lut[:, c] at integer levels
uniform sampler2D u_inv;      // N x 3 RG32F: texel (i, c) = (inv_lut[i, c], inv_lut[i + 1, c])

#if PACKED == 1
// pixel method, packed: 32 values per pixel, value k = q_k * Q_SCALE + Q_OFFSET with q_k a
// 20-bit integer. u_m<t> (t < 4) holds the top 16 bits of values 8t..8t+3 in the low and
// of 8t+4..8t+7 in the high halves of its four uints; u_m4 the low 4 bits, value 8t+4h+c
// in bits 4 (2t + h)..+3 of its uint c. Values: Ww (row-major, 0..8), Aw (9..11), Wc
// (12..20), Ac (21..23), refl (24..26), pos (27..29), the camera's lobe (30), unused (31).
uniform usampler2D u_m0;
uniform usampler2D u_m1;
uniform usampler2D u_m2;
uniform usampler2D u_m3;
uniform usampler2D u_m4;
#ifndef Q_SCALE0
#define Q_SCALE0 vec4(1.0)
#define Q_SCALE1 vec4(1.0)
#define Q_SCALE2 vec4(1.0)
#define Q_SCALE3 vec4(1.0)
#define Q_SCALE4 vec4(1.0)
#define Q_SCALE5 vec4(1.0)
#define Q_SCALE6 vec4(1.0)
#define Q_SCALE7 vec4(1.0)
#define Q_OFFSET0 vec4(0.0)
#define Q_OFFSET1 vec4(0.0)
#define Q_OFFSET2 vec4(0.0)
#define Q_OFFSET3 vec4(0.0)
#define Q_OFFSET4 vec4(0.0)
#define Q_OFFSET5 vec4(0.0)
#define Q_OFFSET6 vec4(0.0)
#define Q_OFFSET7 vec4(0.0)
#endif
#else
// pixel method, float32: RGBA32F textures, row i of Ww (xyz) and Aw[i] (w); same for Wc / Ac.
uniform sampler2D u_w0;
uniform sampler2D u_w1;
uniform sampler2D u_w2;
uniform sampler2D u_c0;
uniform sampler2D u_c1;
uniform sampler2D u_c2;
uniform sampler2D u_refl;     // RGBA32F unit reflection vectors (xyz)
uniform sampler2D u_pos;      // RGBA32F surface points (xyz, metres) and the camera's lobe
                              // (w) = max(dot(refl, normalize(cam_eye - pos)), 0)^gamma
#endif

out vec4 frag_color;

// Forward LUT at integer levels. u_fwd holds reference.lut_forward(fwd_lut, level) for
// every level 0..255, computed by numpy, so this is bit-identical to the reference.
vec3 lut_forward(ivec3 level) {
    vec3 u = (vec3(level) + 0.5) * (1.0 / 256.0);
    return vec3(textureLod(u_fwd, vec2(u.r, 1.0 / 6.0), 0.0).r,
                textureLod(u_fwd, vec2(u.g, 0.5), 0.0).r,
                textureLod(u_fwd, vec2(u.b, 5.0 / 6.0), 0.0).r);
}

// Linear interpolation in the inverse LUT (reference.lut_inverse) at linear position
// t = clamp((y - lo) / (hi - lo), 0, 1) * (N - 1); the LUT is sampled uniformly in the square
// root of that fraction, so the position is warped first. Returns 0..1.
vec3 lut_inverse_at(vec3 t_lin) {
    vec3 t = sqrt(t_lin * (1.0 / float(N_INV - 1))) * float(N_INV - 1);
    ivec3 i0 = min(ivec3(floor(t)), ivec3(N_INV - 2));
    vec3 f = t - vec3(i0);
    vec3 u = (vec3(i0) + 0.5) * (1.0 / float(N_INV));
    vec2 ab0 = textureLod(u_inv, vec2(u.x, 1.0 / 6.0), 0.0).xy;
    vec2 ab1 = textureLod(u_inv, vec2(u.y, 0.5), 0.0).xy;
    vec2 ab2 = textureLod(u_inv, vec2(u.z, 5.0 / 6.0), 0.0).xy;
    vec3 a = vec3(ab0.x, ab1.x, ab2.x);
    vec3 b = vec3(ab0.y, ab1.y, ab2.y);
    return a + (b - a) * f;
}

void main() {
    vec2 uv = v_uv;
#if INPUT == 1
    ivec2 p = ivec2(uv * vec2(GRID_W, GRID_H));
    ivec3 level = yuv420p_levels(p, uv);
#else
    ivec3 level = ivec3(textureLod(u_rgb, uv, 0.0).rgb);
#endif

    vec3 result;
#if METHOD == 1
    {
#if PACKED == 1
        uvec4 t0 = textureLod(u_m0, uv, 0.0);
        uvec4 t1 = textureLod(u_m1, uv, 0.0);
        uvec4 t2 = textureLod(u_m2, uv, 0.0);
        uvec4 t3 = textureLod(u_m3, uv, 0.0);
        uvec4 t4 = textureLod(u_m4, uv, 0.0);
        vec4 v0 = vec4(((t0 & 0xFFFFu) << 4u) | (t4 & 0xFu)) * Q_SCALE0 + Q_OFFSET0;
        vec4 v1 = vec4(((t0 >> 12u) & 0xFFFF0u) | ((t4 >> 4u) & 0xFu)) * Q_SCALE1 + Q_OFFSET1;
        vec4 v2 = vec4(((t1 & 0xFFFFu) << 4u) | ((t4 >> 8u) & 0xFu)) * Q_SCALE2 + Q_OFFSET2;
        vec4 v3 = vec4(((t1 >> 12u) & 0xFFFF0u) | ((t4 >> 12u) & 0xFu)) * Q_SCALE3 + Q_OFFSET3;
        vec4 v4 = vec4(((t2 & 0xFFFFu) << 4u) | ((t4 >> 16u) & 0xFu)) * Q_SCALE4 + Q_OFFSET4;
        vec4 v5 = vec4(((t2 >> 12u) & 0xFFFF0u) | ((t4 >> 20u) & 0xFu)) * Q_SCALE5 + Q_OFFSET5;
        vec4 v6 = vec4(((t3 & 0xFFFFu) << 4u) | ((t4 >> 24u) & 0xFu)) * Q_SCALE6 + Q_OFFSET6;
        vec4 v7 = vec4(((t3 >> 12u) & 0xFFFF0u) | (t4 >> 28u)) * Q_SCALE7 + Q_OFFSET7;
        vec4 w0 = vec4(v0.xyz, v2.y);            // Ww row 0, Aw.x
        vec4 w1 = vec4(v0.w, v1.xy, v2.z);       // Ww row 1, Aw.y
        vec4 w2 = vec4(v1.zw, v2.x, v2.w);       // Ww row 2, Aw.z
        vec4 c0 = vec4(v3.xyz, v5.y);            // Wc row 0, Ac.x
        vec4 c1 = vec4(v3.w, v4.xy, v5.z);       // Wc row 1, Ac.y
        vec4 c2 = vec4(v4.zw, v5.x, v5.w);       // Wc row 2, Ac.z
        vec3 refl = v6.xyz;
        vec4 pos = vec4(v6.w, v7.xyz);           // surface point, camera's lobe
#else
        vec4 w0 = textureLod(u_w0, uv, 0.0);
        vec4 w1 = textureLod(u_w1, uv, 0.0);
        vec4 w2 = textureLod(u_w2, uv, 0.0);
        vec4 c0 = textureLod(u_c0, uv, 0.0);
        vec4 c1 = textureLod(u_c1, uv, 0.0);
        vec4 c2 = textureLod(u_c2, uv, 0.0);
        vec3 refl = textureLod(u_refl, uv, 0.0).xyz;
        vec4 pos = textureLod(u_pos, uv, 0.0);
#endif
        vec4 eye_alpha = v_frame[0];
        float beta = v_frame[1].x;

        vec3 pw = lut_forward(level);
        vec3 cw = vec3(dot(w0.xyz, pw), dot(w1.xyz, pw), dot(w2.xyz, pw)) + vec3(w0.w, w1.w, w2.w);
        vec3 target = eye_alpha.w * cw + beta;
        float lobe_eye = pow(max(dot(refl, normalize(eye_alpha.xyz - pos.xyz)), 0.0), GAMMA);
        vec3 ds = KAPPA * (lobe_eye - pos.w);
        // Rows of M = Wc + diag(ds) Ww; solve M y = target - Ac by the adjugate.
        vec3 r0 = c0.xyz + ds.x * w0.xyz;
        vec3 r1 = c1.xyz + ds.y * w1.xyz;
        vec3 r2 = c2.xyz + ds.z * w2.xyz;
        vec3 b = target - vec3(c0.w, c1.w, c2.w);
        vec3 k0 = cross(r1, r2);
        float det = dot(r0, k0);
        vec3 y = (k0 * b.x + cross(r2, r0) * b.y + cross(r0, r1) * b.z) / det;
        vec3 t = clamp((clamp(y, 0.0, 1.0) - INV_LO) * INV_SCALE, 0.0, float(N_INV - 1));
        result = lut_inverse_at(t);
    }
#elif METHOD == 2
    {
        vec3 pw = lut_forward(level);
        vec4 a0 = v_frame[0];
        vec4 a1 = v_frame[1];
        vec4 a2 = v_frame[2];
        vec3 t = vec3(dot(a0.xyz, pw), dot(a1.xyz, pw), dot(a2.xyz, pw)) + vec3(a0.w, a1.w, a2.w);
        result = lut_inverse_at(clamp(t, 0.0, float(N_INV - 1)));
    }
#else
    result = vec3(level) / 255.0;
#endif
    vec3 out_level = roundEven(clamp(result, 0.0, 1.0) * 255.0);
    frag_color = vec4(out_level / 255.0, 1.0);
}
