#version 330 core
// The GL compensator's fragment shader: fetches what the formula of compensate_core.glsl
// needs and runs it, one fragment path per variant, for the methods identity (0), pixel (1,
// or 3 from the view cache that 4 renders) and paper (2).
//
// Addressing: v_uv (fullscreen.vert.glsl) is the centre of the grid texel this fragment
// computes, row 0 = array row 0, so read-back of rows 0.. gives array rows 0.. again; the
// viewport places the grid and the vertex shader flips it for a window if asked.
//
// Speed on Mesa llvmpipe (docs/BENCHMARKS.md), which the layout follows:
// - The frame is read with NEAREST textureLod(.., 0) at texel centres (~1.5x cheaper than
//   texelFetch from a 2D texture there); the LUTs, the maps and the view cache are buffer
//   textures read with texelFetch (cheaper still: an index, no coordinates).
// - The numbers fixed for a Compensator (grid size, LUT domain, lobe shape) are compiled in as
//   #define literals, and what changes per frame (eye, tone map, the paper method's folded
//   matrices) comes from the vertex shader as flat inputs v_frame[], not from uniforms: a
//   uniform block read here cost 10-20 % more time per draw at 1080p (docs/BENCHMARKS.md).
// - The pixel method's 31 per-pixel values are 8 RGBA32F texels, those of one pixel side by
//   side (reads close in memory). A held eye reads the view cache instead (5 texels, no
//   solve).

// Variant (one program each; llvmpipe would otherwise run every branch for every pixel):
// METHOD 0 identity, 1 pixel, 2 paper, 3 pixel from the view cache, 4 the view cache itself
// (see "View cache" below), 5 pixel for an audience of several viewers (u_eyes), 6 the view
// cache of an audience, 7 pixel with the adaptive tone map (u_field), 8 the same from the view
// cache; INPUT 0 the RGB8UI texture u_rgb, 1 yuv420p planes (yuv.glsl).
#ifndef METHOD
#define METHOD 1
#endif
#ifndef INPUT
#define INPUT 0
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
// The inverse LUT's squared position of the pixel method's y: pixel_t2(y, SQ_SCALE, SQ_OFF,
// SQ_LO, SQ_HI) (compensate_core.glsl; viewcomp.calib.model.shader_inputs.inverse_position).
#ifndef SQ_SCALE
#define SQ_SCALE vec3(1.0)
#define SQ_OFF vec3(0.0)
#define SQ_LO vec3(0.0)
#define SQ_HI vec3(1.0)
#endif
// The specular lobe: LOBE_N table entries (u_lobe), the half-vector angle (true) or the
// mirror angle (false) (viewcomp.calib.model.lobe).
#ifndef LOBE_N
#define LOBE_N 2
#endif
#ifndef LOBE_HALF
#define LOBE_HALF true
#endif
#ifndef LOBE_BLACK
#define LOBE_BLACK vec3(0.0)  // the projector leak's share of the black level
#endif
// The adaptive tone map (METHODs 7, 8): FIELD_NX x FIELD_NY nodes (u_field), FIELD_STEP their
// spacing in pixels^-1, GAMUT_K and GAMUT_LIMIT its constants, GAMUT_LUMA the luminance
// weights (viewcomp.calib.model.shader_inputs.gamut_constants, field_step); the field's hue
// weight comes per frame as v_frame[1].y.
#ifndef FIELD_NX
#define FIELD_NX 2
#define FIELD_NY 2
#define FIELD_STEP vec2(1.0)
#endif
#ifndef GAMUT_K
#define GAMUT_K vec3(0.1, 1e-6, 2.0)
#define GAMUT_LIMIT 1000.0
#define GAMUT_LUMA vec3(0.2126, 0.7152, 0.0722)
#endif
#ifndef MAX_VIEWERS
#define MAX_VIEWERS 16  // viewcomp.calib.world.audience.MAX_VIEWERS
#endif

#include "yuv.glsl"
#include "compensate_core.glsl"

in vec2 v_uv;
// Per frame. pixel: [0] = (eye.xyz metres, alpha), [1].x = beta. paper: rows a0..a2 of
// paper_t2 (compensate_core.glsl) in [0]..[2].
flat in vec4 v_frame[4];

uniform usampler2D u_rgb;     // frame, 8-bit levels (RGB8UI)
uniform samplerBuffer u_fwd;  // R32F, 3 x 256: [256 c + l] = fwd_lut[l, c] at integer levels
uniform samplerBuffer u_inv;  // RG32F, 3 x N: [N c + i] = (inv_lut[i, c], inv_lut[i + 1, c])
// pixel method: the per-pixel maps (viewcomp.calib.model.shader_inputs.pixel_texels), 8 RGBA32F
// texels per pixel side by side: texel k of grid pixel (x, y) is u_maps[8 (y W + x) + k].
uniform samplerBuffer u_maps;
uniform samplerBuffer u_lobe;  // RGBA32F, LOBE_N: the lobe table (RuntimeModel.lobe) | 0
// METHODs 5 and 6: the audience, u_n_eyes viewers (eye.xyz metres, weight; weights sum to
// 1). Uniforms, not flat inputs: these variants run per eye change, not per frame.
uniform vec4 u_eyes[MAX_VIEWERS];
uniform int u_n_eyes;
// METHODs 7 and 8: the adaptive tone map's field, each row of nodes interpolated along x at
// every column (RG32F, [W j + x] = (gain, offset); shader_inputs.field_columns, written per
// frame: 2 reads a pixel instead of 4 nodes and their weights); and per pixel the luminance
// row (k^T Ww | k . Aw) of the white screen's light (shader_inputs.luma_rows).
uniform samplerBuffer u_fcol;
uniform samplerBuffer u_luma;

// The field's (gain, offset) at grid pixel p (field_rows; gamut.field_at).
vec2 field_at(ivec2 p) {
    float fy;
    ivec2 j = field_rows(p.y, FIELD_NY, FIELD_STEP.y, fy);
    vec2 top = texelFetch(u_fcol, j.x * GRID_W + p.x).xy;
    vec2 bot = texelFetch(u_fcol, j.y * GRID_W + p.x).xy;
    return top + (bot - top) * fy;
}

vec2 inv_pair(int c, int i) {
    return texelFetch(u_inv, N_INV * c + i).xy;
}

vec3 lobe_entry(int i) {
    return texelFetch(u_lobe, i).rgb;
}

PixelMaps read_maps(ivec2 p) {
    int base = (p.y * GRID_W + p.x) * 8;
    return pixel_maps(texelFetch(u_maps, base), texelFetch(u_maps, base + 1),
                      texelFetch(u_maps, base + 2), texelFetch(u_maps, base + 3),
                      texelFetch(u_maps, base + 4), texelFetch(u_maps, base + 5),
                      texelFetch(u_maps, base + 6), texelFetch(u_maps, base + 7));
}

// View cache (pixel method, the eye held still): view_terms (compensate_core.glsl) per
// pixel, written by METHOD 4 as 5 RGBA32F texels, (G | a) rows 0..2, (b, 0), (d, 0), in a
// VIEW_BX x VIEW_BY block of a 2D render target (VIEW_BX W wide); one fragment per texel,
// each solving its pixel once (5x the work, once per eye). The target's rows are then copied
// into the buffer texture u_view (row-major), and METHOD 3 reads 5 texels instead of 8 and
// skips the lobe and the solve. Same formula, other rounding: tested against the reference
// like METHOD 1. The spare w of texels 3 and 4 hold the pixel's grey range (n_lo, n_hi) at
// the eye (its reach; grey_range), which METHOD 8 reads.
#ifndef VIEW_BX
#define VIEW_BX 5
#define VIEW_BY 1
#endif
uniform samplerBuffer u_view;
// Texel k of grid pixel p: row VIEW_BY p.y + k / VIEW_BX, column VIEW_BX p.x + k % VIEW_BX.
#define VIEW(p, k) texelFetch(u_view, (VIEW_BY * (p).y + (k) / VIEW_BX) * (VIEW_BX * GRID_W) + VIEW_BX * (p).x + (k) % VIEW_BX)

out vec4 frag_color;

// The audience's normal equations at one pixel, summed over the viewers in order
// (audience_add; reference.audience_normal).
void audience_normal(PixelMaps m, out mat3 nn, out mat3 s, out vec3 q) {
    nn = mat3(0.0);
    s = mat3(0.0);
    q = vec3(0.0);
    for (int k = 0; k < u_n_eyes; ++k) {
        audience_add(m, u_eyes[k].xyz, u_eyes[k].w, LOBE_HALF, LOBE_N, LOBE_BLACK, nn, s, q);
    }
}

// Forward LUT at integer levels. u_fwd holds reference.lut_forward(fwd_lut, level) for
// every level 0..255, computed by numpy, so this is bit-identical to the reference.
vec3 lut_forward(ivec3 level) {
    return vec3(texelFetch(u_fwd, level.r).r, texelFetch(u_fwd, 256 + level.g).r,
                texelFetch(u_fwd, 512 + level.b).r);
}

void main() {
#if METHOD == 4 || METHOD == 6
    // One texel of the view cache: viewport = the cache texture, origin at (0, 0).
    ivec2 q = ivec2(gl_FragCoord.xy);
    ivec2 block = ivec2(VIEW_BX, VIEW_BY);
    ivec2 sub = q - (q / block) * block;
    int k = sub.x + VIEW_BX * sub.y;
    vec4 g0, g1, g2;
    vec3 b, d;
#if METHOD == 4
    view_terms(read_maps(q / block), v_frame[0].xyz, LOBE_HALF, LOBE_N, LOBE_BLACK, SQ_SCALE,
               SQ_OFF, g0, g1, g2, b, d);
#else
    PixelMaps m = read_maps(q / block);
    mat3 nn, s;
    vec3 qv;
    audience_normal(m, nn, s, qv);
    audience_view_terms(nn, s, qv, m, SQ_SCALE, SQ_OFF, g0, g1, g2, b, d);
#endif
    vec2 reach = grey_range(b / SQ_SCALE, (SQ_OFF - d) / SQ_SCALE, GAMUT_K.y, GAMUT_LIMIT);
    frag_color = k == 0 ? g0 : (k == 1 ? g1 : (k == 2 ? g2 : (k == 3 ? vec4(b, reach.x)
                 : (k == 4 ? vec4(d, reach.y) : vec4(0.0)))));
#else
    vec2 uv = v_uv;
    ivec2 p = ivec2(uv * vec2(GRID_W, GRID_H));  // this fragment's grid pixel
#if INPUT == 1
    ivec3 level = yuv420p_levels(p, uv);
#else
    ivec3 level = ivec3(textureLod(u_rgb, uv, 0.0).rgb);
#endif

#if METHOD == 1
    vec3 y = solve_pixel(read_maps(p), lut_forward(level), v_frame[0].xyz, v_frame[0].w,
                         v_frame[1].x, LOBE_HALF, LOBE_N, LOBE_BLACK);
    vec3 result = lut_inverse_sq(pixel_t2(y, SQ_SCALE, SQ_OFF, SQ_LO, SQ_HI));
#elif METHOD == 5
    PixelMaps m = read_maps(p);
    mat3 nn, s;
    vec3 q;
    audience_normal(m, nn, s, q);
    vec3 y = solve_audience(nn, s, q, m, lut_forward(level), v_frame[0].w, v_frame[1].x);
    vec3 result = lut_inverse_sq(pixel_t2(y, SQ_SCALE, SQ_OFF, SQ_LO, SQ_HI));
#elif METHOD == 3
    vec3 t2 = cached_t2(VIEW(p, 0), VIEW(p, 1), VIEW(p, 2), VIEW(p, 3).xyz, VIEW(p, 4).xyz,
                        lut_forward(level), v_frame[0].w, v_frame[1].x);
    vec3 result = lut_inverse_sq(clamp(t2, SQ_LO, SQ_HI));
#elif METHOD == 7
    // The adaptive tone map, solved at the eye: u, v, c unscaled (view_terms with scale 1).
    PixelMaps m = read_maps(p);
    vec4 g0, g1, g2;
    vec3 b, d;
    view_terms(m, v_frame[0].xyz, LOBE_HALF, LOBE_N, LOBE_BLACK, vec3(1.0), vec3(0.0), g0, g1,
               g2, b, d);
    vec3 pw = lut_forward(level);
    vec3 u = vec3(dot(g0.xyz, pw), dot(g1.xyz, pw), dot(g2.xyz, pw)) + vec3(g0.w, g1.w, g2.w);
    vec3 cw = vec3(dot(m.w0.xyz, pw), dot(m.w1.xyz, pw), dot(m.w2.xyz, pw))
        + vec3(m.w0.w, m.w1.w, m.w2.w);
    vec3 y = soft_light(u, b, -d, dot(GAMUT_LUMA, cw), field_at(p),
                        grey_range(b, -d, GAMUT_K.y, GAMUT_LIMIT), GAMUT_K, vec3(1.0),
                        v_frame[1].y);
    vec3 result = lut_inverse_sq(pixel_t2(y, SQ_SCALE, SQ_OFF, SQ_LO, SQ_HI));
#elif METHOD == 8
    // The adaptive tone map from the view cache: its terms are scaled to the LUT position
    // (view_terms: s u, s v and s c = off - d, s = SQ_SCALE), and soft_light works in those
    // units (top = s), so t2 = s y - off; the reach is cached beside them.
    vec3 pw = lut_forward(level);
    vec4 g0 = VIEW(p, 0), g1 = VIEW(p, 1), g2 = VIEW(p, 2), tb = VIEW(p, 3), td = VIEW(p, 4);
    vec3 us = vec3(dot(g0.xyz, pw), dot(g1.xyz, pw), dot(g2.xyz, pw)) + vec3(g0.w, g1.w, g2.w);
    vec4 lr = texelFetch(u_luma, p.y * GRID_W + p.x);
    vec3 ys = soft_light(us, tb.xyz, SQ_OFF - td.xyz, dot(lr.xyz, pw) + lr.w, field_at(p),
                         vec2(tb.w, td.w), GAMUT_K, SQ_SCALE, v_frame[1].y);
    vec3 result = lut_inverse_sq(clamp(ys - SQ_OFF, SQ_LO, SQ_HI));
#elif METHOD == 2
    vec3 result = lut_inverse_sq(paper_t2(v_frame[0], v_frame[1], v_frame[2],
                                          lut_forward(level), float((N_INV - 1) * (N_INV - 1))));
#else
    vec3 result = vec3(level) / 255.0;
#endif
    frag_color = vec4(quantise(result), 1.0);
#endif
}
