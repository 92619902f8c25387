// yuv420p -> RGB 8-bit levels, in fixed point, bit-exact with
// viewcomp.rt.frames.yuv420p_to_rgb (the CPU backend uses that function, so both backends
// compensate the very same RGB levels).
//
// Luma is an R8UI texture W x H (texel (x, y) = plane[y, x], row 0 first); chroma is one
// RG8UI texture ceil(W/2) x ceil(H/2) holding (U, V) per texel (half the reads). Chroma is
// upsampled bilinearly for MPEG-2/H.264 "left" siting (co-sited with even luma columns,
// midway between luma rows) with integer weights summing to 8 (x: 2 | 1+1, y: 3+1). The
// matrix (BT.601/BT.709, limited/full range) comes from the stream's metadata as the
// literals YUV_K / YUV_KG, integers at scale 2^16 (viewcomp.rt.frames.yuv_coefficients);
// the includer defines GRID_W and GRID_H (the luma size).

#ifndef YUV_K
#define YUV_K ivec4(76309, 117489, 138438, 16)   // (cy, cr->R, cb->B, luma offset): BT.709
#define YUV_KG ivec2(-13975, -34925)             // (cb->G, cr->G), limited range
#endif

uniform usampler2D u_y;
uniform usampler2D u_uv;

const int YUV_SHIFT = 19;                  // 16 (coefficients) + 3 (chroma weights 8)
const int YUV_HALF = 1 << (YUV_SHIFT - 1);
const int YUV_MAX = 255 << YUV_SHIFT;
const ivec2 YUV_CSIZE = ivec2((GRID_W + 1) / 2, (GRID_H + 1) / 2);

// Sums of the weighted (U, V) samples around luma pixel p (weights total 8), read with
// textureLod() at chroma texel centres (cheaper than texelFetch on llvmpipe).
ivec2 chroma8(ivec2 p) {
    int xc = p.x >> 1;
    int yc = p.y >> 1;
    int x1 = ((p.x & 1) == 1) ? min(xc + 1, YUV_CSIZE.x - 1) : xc;
    int y1 = ((p.y & 1) == 1) ? min(yc + 1, YUV_CSIZE.y - 1) : max(yc - 1, 0);
    vec2 u = (vec2(xc, x1) + 0.5) * (1.0 / float(YUV_CSIZE.x));
    vec2 v = (vec2(yc, y1) + 0.5) * (1.0 / float(YUV_CSIZE.y));
    uvec2 n0 = textureLod(u_uv, vec2(u.x, v.x), 0.0).rg;
    uvec2 n1 = textureLod(u_uv, vec2(u.y, v.x), 0.0).rg;
    uvec2 f0 = textureLod(u_uv, vec2(u.x, v.y), 0.0).rg;
    uvec2 f1 = textureLod(u_uv, vec2(u.y, v.y), 0.0).rg;
    ivec2 near = ivec2(n0 + n1);
    ivec2 far = ivec2(f0 + f1);
    return 3 * near + far;
}

int yuv_level(int acc) {
    return clamp(acc + YUV_HALF, 0, YUV_MAX) >> YUV_SHIFT;
}

// RGB levels 0..255 of luma pixel p (x right, y = plane row); uv = centre of texel p.
ivec3 yuv420p_levels(ivec2 p, vec2 uv) {
    int y8 = (int(textureLod(u_y, uv, 0.0).r) - YUV_K.w) * 8;
    ivec2 c = chroma8(p) - 1024;
    int cb = c.x;
    int cr = c.y;
    int luma = YUV_K.x * y8;
    return ivec3(
        yuv_level(luma + YUV_K.y * cr),
        yuv_level(luma + YUV_KG.x * cb + YUV_KG.y * cr),
        yuv_level(luma + YUV_K.z * cb));
}
