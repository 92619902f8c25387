// yuv420p -> RGB 8-bit levels, in fixed point, bit-exact with
// viewcomp.rt.frames.yuv420p_to_rgb (the CPU backend uses that function, so both backends
// compensate the very same RGB levels).
//
// Luma is an R8UI texture W x H (texel (x, y) = plane[y, x], row 0 first); chroma is one
// RG8UI texture ceil(W/2) x ceil(H/2) holding (U, V) per texel (half the fetches). Chroma is upsampled bilinearly for MPEG-2/H.264 "left" siting
// (co-sited with even luma columns, midway between luma rows) with integer weights summing
// to 8 (x: 2 | 1+1, y: 3+1). The matrix (BT.601/BT.709, limited/full range) comes from the
// stream's metadata through u_yuv_k/u_yuv_kg, integers at scale 2^16
// (viewcomp.rt.frames.yuv_coefficients).

uniform usampler2D u_y;
uniform usampler2D u_uv;
uniform ivec4 u_yuv_k;   // (cy, cr->R, cb->B, luma offset)
uniform ivec2 u_yuv_kg;  // (cb->G, cr->G), both <= 0

const int YUV_SHIFT = 19;                  // 16 (coefficients) + 3 (chroma weights 8)
const int YUV_HALF = 1 << (YUV_SHIFT - 1);
const int YUV_MAX = 255 << YUV_SHIFT;

// Sums of the weighted (U, V) samples around luma pixel p (weights total 8).
ivec2 chroma8(ivec2 p) {
    ivec2 size = textureSize(u_uv, 0);
    int xc = p.x >> 1;
    int yc = p.y >> 1;
    int x1 = ((p.x & 1) == 1) ? min(xc + 1, size.x - 1) : xc;
    int y1 = ((p.y & 1) == 1) ? min(yc + 1, size.y - 1) : max(yc - 1, 0);
    ivec2 near = ivec2(texelFetch(u_uv, ivec2(xc, yc), 0).rg + texelFetch(u_uv, ivec2(x1, yc), 0).rg);
    ivec2 far = ivec2(texelFetch(u_uv, ivec2(xc, y1), 0).rg + texelFetch(u_uv, ivec2(x1, y1), 0).rg);
    return 3 * near + far;
}

int yuv_level(int acc) {
    return clamp(acc + YUV_HALF, 0, YUV_MAX) >> YUV_SHIFT;
}

// RGB levels 0..255 of luma pixel p (x right, y = plane row).
ivec3 yuv420p_levels(ivec2 p) {
    int y8 = (int(texelFetch(u_y, p, 0).r) - u_yuv_k.w) * 8;
    ivec2 c = chroma8(p) - 1024;
    int cb = c.x;
    int cr = c.y;
    int luma = u_yuv_k.x * y8;
    return ivec3(
        yuv_level(luma + u_yuv_k.y * cr),
        yuv_level(luma + u_yuv_kg.x * cb + u_yuv_kg.y * cr),
        yuv_level(luma + u_yuv_k.z * cb));
}
