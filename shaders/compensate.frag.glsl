#version 330 core
// The per-frame formula of docs/RUNTIME.md, one fragment path for the methods identity (0),
// pixel (1, or 3 from the view cache that 4 renders) and paper (2); the numpy reference is
// viewcomp.calib.reference.compensate.
//
// Addressing: v_uv (fullscreen.vert.glsl) is the centre of the grid texel this fragment
// computes, row 0 = array row 0, so read-back of rows 0.. gives array rows 0.. again; the
// viewport places the grid and the vertex shader flips it for a window if asked.
//
// Speed on Mesa llvmpipe (docs/BENCHMARKS.md), which the layout follows:
// - The frame is read with NEAREST textureLod(.., 0) at texel centres (~1.5x cheaper than
//   texelFetch from a 2D texture there); the LUTs, the maps and the view cache are buffer
//   textures read with texelFetch (cheaper still: an index, no coordinates).
// - No uniforms: llvmpipe pays per pixel for every uniform component a fragment shader
//   reads. What is fixed for a Compensator (grid size, LUT domain, lobe, the packed maps'
//   scales) is compiled in as #define literals; what changes per frame (eye, tone map, the
//   paper method's matrices) comes from the vertex shader as flat inputs v_frame[].
// - The pixel method's 31 per-pixel values are float32 (8 RGBA32F reads) or, opt-in, 20-bit
//   fixed point in 5 RGBA32UI texels (5 reads, 80 instead of 128 bytes; see Compensator),
//   the texels of one pixel side by side (reads close in memory). A held eye reads the view
//   cache instead (5 texels, no solve).
//
// Output: level = roundEven(255 * clamp(out, 0, 1)) (= np.rint), written as level / 255 so
// that any float -> unorm8 conversion of the framebuffer returns exactly that level.

// Variant (one program each; llvmpipe would otherwise run every branch for every pixel):
// METHOD 0 identity, 1 pixel, 2 paper, 3 pixel from the view cache, 4 the view cache itself
// (see "View cache" below); INPUT 0 the RGB8UI texture u_rgb, 1 yuv420p planes
// (yuv.glsl); PACKED 1 the 20-bit maps, 0 the float32 maps (both in u_maps).
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
// The inverse LUT's squared position t2 = (N - 1)^2 (y - lo) / (hi - lo) of a value y, over
// y in [0, 1] and within [0, (N - 1)^2]: t2 = clamp(SQ_SCALE y - SQ_OFF, SQ_LO, SQ_HI) (see
// lut_inverse_sq; the bounds of both clamps folded into one pair, Compensator._sq_consts).
#ifndef SQ_SCALE
#define SQ_SCALE vec3(1.0)
#define SQ_OFF vec3(0.0)
#define SQ_LO vec3(0.0)
#define SQ_HI vec3(1.0)
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
// A = diag(s) alpha Wc_inv Ww in [i].xyz and c_i in [i].w, with s = (N - 1)^2 / (hi - lo) and
// c = s (beta Wc_inv 1 - lo): the inverse LUT's squared position t2 is A fwd(I) + c (folded
// on the CPU; see lut_inverse_sq).
flat in vec4 v_frame[4];

uniform usampler2D u_rgb;     // frame, 8-bit levels (RGB8UI)
// The LUTs, the maps and the view cache are buffer textures read with texelFetch (on
// llvmpipe ~0.7x the cost of NEAREST textureLod from 2D textures: no coordinate arithmetic).
uniform samplerBuffer u_fwd;  // R32F, 3 x 256: [256 c + l] = fwd_lut[l, c] at integer levels
uniform samplerBuffer u_inv;  // RG32F, 3 x N: [N c + i] = (inv_lut[i, c], inv_lut[i + 1, c])

// pixel method: the per-pixel maps, MAP_N texels per pixel side by side (neighbours in
// memory: on llvmpipe half the cost of one texture per map): texel k of grid pixel (x, y) is
// u_maps[(y W + x) MAP_N + k].
#ifndef MAP_N
#define MAP_N 8
#endif
#if PACKED == 1
// Packed (RGBA32UI, 5 texels a pixel): 32 values per pixel, value k = q_k * Q_SCALE +
// Q_OFFSET with q_k a 20-bit integer. Texel t < 4 holds the top 16 bits of values 8t..8t+3
// in the low and of 8t+4..8t+7 in the high halves of its four uints; texel 4 the low 4 bits,
// value 8t+4h+c in bits 4 (2t + h)..+3 of its uint c. Values: Ww (row-major, 0..8), Aw
// (9..11), Wc (12..20), Ac (21..23), refl (24..26), pos (27..29), the camera's lobe (30),
// unused (31).
uniform usamplerBuffer u_maps;
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
// Float32 (RGBA32F, 8 texels a pixel): rows 0..2 of Ww (xyz) with Aw[row] (w); the same for
// Wc / Ac (texels 3..5); the unit reflection vector (6, xyz); the surface point (7, xyz,
// metres) with the camera's lobe (w) = max(dot(refl, normalize(cam_eye - pos)), 0)^gamma.
uniform samplerBuffer u_maps;
#endif
#define MAP(base, k) texelFetch(u_maps, (base) + (k))

// View cache (pixel method, the eye held still). For a fixed eye the per-pixel solve is
// linear in the tone map: y = M^-1 (alpha (Ww Pw + Aw) + beta 1 - Ac)
//                             = alpha (G Pw + a) + beta b - d,
// with G = M^-1 Ww, a = M^-1 Aw, b = M^-1 1, d = M^-1 Ac. METHOD 4 writes them, per pixel,
// with row i scaled by SQ_SCALE_i and SQ_OFF added to d, so that the same formula gives the
// inverse LUT's t2 = SQ_SCALE y - SQ_OFF directly (no per-frame scaling), as 5 RGBA32F
// texels in a VIEW_BX x VIEW_BY block of a 2D render target (VIEW_BX W wide): texel i < 3 =
// (row i of G, a_i), texel 3 = (b, 0), texel 4 = (d, 0); one fragment per
// texel, each solving its pixel once (5x the work, once per eye). The target's rows are
// then copied into the buffer texture u_view (row-major), and METHOD 3 reads 5 texels
// instead of 8 and skips the lobe and the solve. Same formula, other rounding: tested
// against the reference like METHOD 1.
#ifndef VIEW_BX
#define VIEW_BX 5
#define VIEW_BY 1
#endif
uniform samplerBuffer u_view;
// Texel k of grid pixel p: row VIEW_BY p.y + k / VIEW_BX, column VIEW_BX p.x + k % VIEW_BX.
#define VIEW(p, k) texelFetch(u_view, (VIEW_BY * (p).y + (k) / VIEW_BX) * (VIEW_BX * GRID_W) + VIEW_BX * (p).x + (k) % VIEW_BX)

// The pixel method's maps at grid pixel p: rows of Ww | Aw (w0..w2), of Wc | Ac (c0..c2),
// the reflection vector and the surface point | the camera's lobe.
struct PixelMaps {
    vec4 w0, w1, w2, c0, c1, c2;
    vec3 refl;
    vec4 pos;
};

PixelMaps read_maps(ivec2 p) {
    int base = (p.y * GRID_W + p.x) * MAP_N;
    PixelMaps m;
#if PACKED == 1
    uvec4 t0 = MAP(base, 0);
    uvec4 t1 = MAP(base, 1);
    uvec4 t2 = MAP(base, 2);
    uvec4 t3 = MAP(base, 3);
    uvec4 t4 = MAP(base, 4);
    vec4 v0 = vec4(((t0 & 0xFFFFu) << 4u) | (t4 & 0xFu)) * Q_SCALE0 + Q_OFFSET0;
    vec4 v1 = vec4(((t0 >> 12u) & 0xFFFF0u) | ((t4 >> 4u) & 0xFu)) * Q_SCALE1 + Q_OFFSET1;
    vec4 v2 = vec4(((t1 & 0xFFFFu) << 4u) | ((t4 >> 8u) & 0xFu)) * Q_SCALE2 + Q_OFFSET2;
    vec4 v3 = vec4(((t1 >> 12u) & 0xFFFF0u) | ((t4 >> 12u) & 0xFu)) * Q_SCALE3 + Q_OFFSET3;
    vec4 v4 = vec4(((t2 & 0xFFFFu) << 4u) | ((t4 >> 16u) & 0xFu)) * Q_SCALE4 + Q_OFFSET4;
    vec4 v5 = vec4(((t2 >> 12u) & 0xFFFF0u) | ((t4 >> 20u) & 0xFu)) * Q_SCALE5 + Q_OFFSET5;
    vec4 v6 = vec4(((t3 & 0xFFFFu) << 4u) | ((t4 >> 24u) & 0xFu)) * Q_SCALE6 + Q_OFFSET6;
    vec4 v7 = vec4(((t3 >> 12u) & 0xFFFF0u) | (t4 >> 28u)) * Q_SCALE7 + Q_OFFSET7;
    m.w0 = vec4(v0.xyz, v2.y);            // Ww row 0, Aw.x
    m.w1 = vec4(v0.w, v1.xy, v2.z);       // Ww row 1, Aw.y
    m.w2 = vec4(v1.zw, v2.x, v2.w);       // Ww row 2, Aw.z
    m.c0 = vec4(v3.xyz, v5.y);            // Wc row 0, Ac.x
    m.c1 = vec4(v3.w, v4.xy, v5.z);       // Wc row 1, Ac.y
    m.c2 = vec4(v4.zw, v5.x, v5.w);       // Wc row 2, Ac.z
    m.refl = v6.xyz;
    m.pos = vec4(v6.w, v7.xyz);           // surface point, camera's lobe
#else
    m.w0 = MAP(base, 0);
    m.w1 = MAP(base, 1);
    m.w2 = MAP(base, 2);
    m.c0 = MAP(base, 3);
    m.c1 = MAP(base, 4);
    m.c2 = MAP(base, 5);
    m.refl = MAP(base, 6).xyz;
    m.pos = MAP(base, 7);
#endif
    return m;
}

// The adjugate of M = Wc + diag(ds) Ww at the eye, as columns k0, k1, k2 (M^-1 = [k0 k1 k2]
// / det), ds = kappa ((R.V_eye)^+^gamma - the camera's lobe).
float adjugate(PixelMaps m, vec3 eye, out vec3 k0, out vec3 k1, out vec3 k2) {
    float lobe_eye = pow(max(dot(m.refl, normalize(eye - m.pos.xyz)), 0.0), GAMMA);
    vec3 ds = KAPPA * (lobe_eye - m.pos.w);
    vec3 r0 = m.c0.xyz + ds.x * m.w0.xyz;
    vec3 r1 = m.c1.xyz + ds.y * m.w1.xyz;
    vec3 r2 = m.c2.xyz + ds.z * m.w2.xyz;
    k0 = cross(r1, r2);
    k1 = cross(r2, r0);
    k2 = cross(r0, r1);
    return dot(r0, k0);
}

out vec4 frag_color;

// Forward LUT at integer levels. u_fwd holds reference.lut_forward(fwd_lut, level) for
// every level 0..255, computed by numpy, so this is bit-identical to the reference.
vec3 lut_forward(ivec3 level) {
    return vec3(texelFetch(u_fwd, level.r).r, texelFetch(u_fwd, 256 + level.g).r,
                texelFetch(u_fwd, 512 + level.b).r);
}

// Linear interpolation in the inverse LUT (reference.lut_inverse). The LUT is sampled
// uniformly in the square root of the fraction x = clamp((y - lo) / (hi - lo), 0, 1), so the
// position is t = sqrt(x) (N - 1) = sqrt(t2) with t2 = x (N - 1)^2 in [0, (N - 1)^2], which
// the callers compute with the scale folded into their constants. t >= 0 truncates to its
// floor, and at t = N - 1 the last pair (inv_lut[N - 1] twice) applies. Returns 0..1.
vec3 lut_inverse_sq(vec3 t2) {
    vec3 t = sqrt(t2);
    ivec3 i0 = ivec3(t);
    vec3 f = t - vec3(i0);
    vec2 ab0 = texelFetch(u_inv, i0.x).xy;
    vec2 ab1 = texelFetch(u_inv, N_INV + i0.y).xy;
    vec2 ab2 = texelFetch(u_inv, 2 * N_INV + i0.z).xy;
    vec3 a = vec3(ab0.x, ab1.x, ab2.x);
    vec3 b = vec3(ab0.y, ab1.y, ab2.y);
    return a + (b - a) * f;
}

void main() {
#if METHOD == 4
    // One texel of the view cache: viewport = the cache texture, origin at (0, 0).
    ivec2 q = ivec2(gl_FragCoord.xy);
    ivec2 block = ivec2(VIEW_BX, VIEW_BY);
    ivec2 sub = q - (q / block) * block;
    int k = sub.x + VIEW_BX * sub.y;
    PixelMaps m = read_maps(q / block);
    vec3 k0, k1, k2;
    float det = adjugate(m, v_frame[0].xyz, k0, k1, k2);
    vec3 inv_det = SQ_SCALE / det;  // rows scaled for the inverse LUT's t2 (METHOD 3)
    vec3 g0 = (k0 * m.w0.x + k1 * m.w1.x + k2 * m.w2.x) * inv_det;  // column 0 of G
    vec3 g1 = (k0 * m.w0.y + k1 * m.w1.y + k2 * m.w2.y) * inv_det;
    vec3 g2 = (k0 * m.w0.z + k1 * m.w1.z + k2 * m.w2.z) * inv_det;
    vec3 a = (k0 * m.w0.w + k1 * m.w1.w + k2 * m.w2.w) * inv_det;
    vec3 b = (k0 + k1 + k2) * inv_det;
    vec3 d = (k0 * m.c0.w + k1 * m.c1.w + k2 * m.c2.w) * inv_det + SQ_OFF;
    int i = min(k, 2);
    vec4 row = vec4(g0[i], g1[i], g2[i], a[i]);
    frag_color = k < 3 ? row : (k == 3 ? vec4(b, 0.0) : (k == 4 ? vec4(d, 0.0) : vec4(0.0)));
#else
    vec2 uv = v_uv;
    ivec2 p = ivec2(uv * vec2(GRID_W, GRID_H));  // this fragment's grid pixel
#if INPUT == 1
    ivec3 level = yuv420p_levels(p, uv);
#else
    ivec3 level = ivec3(textureLod(u_rgb, uv, 0.0).rgb);
#endif

    vec3 result;
#if METHOD == 1
    {
        PixelMaps m = read_maps(p);
        vec4 eye_alpha = v_frame[0];
        float beta = v_frame[1].x;
        vec3 pw = lut_forward(level);
        vec3 cw = vec3(dot(m.w0.xyz, pw), dot(m.w1.xyz, pw), dot(m.w2.xyz, pw))
            + vec3(m.w0.w, m.w1.w, m.w2.w);
        vec3 target = eye_alpha.w * cw + beta;
        // Solve M y = target - Ac by the adjugate.
        vec3 k0, k1, k2;
        float det = adjugate(m, eye_alpha.xyz, k0, k1, k2);
        vec3 b = target - vec3(m.c0.w, m.c1.w, m.c2.w);
        vec3 y = (k0 * b.x + k1 * b.y + k2 * b.z) / det;
        result = lut_inverse_sq(clamp(SQ_SCALE * y - SQ_OFF, SQ_LO, SQ_HI));
    }
#elif METHOD == 3
    {
        vec4 g0 = VIEW(p, 0);
        vec4 g1 = VIEW(p, 1);
        vec4 g2 = VIEW(p, 2);
        vec3 bv = VIEW(p, 3).xyz;
        vec3 dv = VIEW(p, 4).xyz;
        float alpha = v_frame[0].w;
        float beta = v_frame[1].x;
        vec3 pw = lut_forward(level);
        vec3 gp = vec3(dot(g0.xyz, pw), dot(g1.xyz, pw), dot(g2.xyz, pw))
            + vec3(g0.w, g1.w, g2.w);
        // The cache holds SQ_SCALE (G, a, b) and SQ_SCALE d + SQ_OFF: this is t2 unclamped.
        vec3 t2 = alpha * gp + beta * bv - dv;
        result = lut_inverse_sq(clamp(t2, SQ_LO, SQ_HI));
    }
#elif METHOD == 2
    {
        vec3 pw = lut_forward(level);
        vec4 a0 = v_frame[0];
        vec4 a1 = v_frame[1];
        vec4 a2 = v_frame[2];
        vec3 t2 = vec3(dot(a0.xyz, pw), dot(a1.xyz, pw), dot(a2.xyz, pw)) + vec3(a0.w, a1.w, a2.w);
        result = lut_inverse_sq(clamp(t2, 0.0, float((N_INV - 1) * (N_INV - 1))));
    }
#else
    result = vec3(level) / 255.0;
#endif
    vec3 out_level = roundEven(clamp(result, 0.0, 1.0) * 255.0);
    frag_color = vec4(out_level / 255.0, 1.0);
#endif
}
