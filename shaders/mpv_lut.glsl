// What the mpv hooks of `viewcomp export-mpv` (mpv_pixel.glsl, mpv_paper.glsl) share: the
// formula (compensate_core.glsl, as in the GL compensator) and mpv's sampling of the LUTs.
// mpv runs a hook as a HOOK OUTPUT pass: hook() per output pixel, with HOOKED_pos (the
// pixel's texture coordinate, 0..1, row 0 of the image at 0), HOOKED_tex (the frame, 0..1)
// and the TEXTURE sections as samplers of their names. viewcomp.rt.export.mpv assembles a
// hook: its #define lines (literals) first, then the file with its includes expanded.
//
// Defines: VC_GRID (vec2) the calibration grid's width and height in pixels; VC_LUT_W the
// width of VC_LUT; VC_N_INV the inverse LUT's entries N.
// VC_LUT has 3 rows: the forward LUT, the inverse LUT and (pixel method) the lobe table.

#include "compensate_core.glsl"

// VC_LUT row 0: the forward LUT at levels 0..255; row 1: the inverse LUT's N entries (RGB);
// row 2: the lobe table (RGB). The texture coordinate of row r is (r + 0.5) / 3.
vec4 vc_lut(float x, float row) {
    return texture(VC_LUT, vec2((x + 0.5) / VC_LUT_W, row));
}

vec2 inv_pair(int c, int i) {
    vec4 a = vc_lut(float(i), 0.5);
    vec4 b = vc_lut(float(min(i + 1, VC_N_INV - 1)), 0.5);
    return vec2(a[c], b[c]);
}

vec3 lobe_entry(int i) {
    return vc_lut(float(i), 2.5 / 3.0).rgb;
}

// Forward LUT at fractional levels 0..255 (video after mpv's yuv -> RGB is not on integer
// levels): linear interpolation, as reference.lut_forward.
vec3 vc_forward(vec3 level) {
    vec3 t = clamp(level, 0.0, 255.0);
    vec3 i0 = min(floor(t), vec3(254.0));
    vec3 a = vec3(vc_lut(i0.r, 0.5 / 3.0).r, vc_lut(i0.g, 0.5 / 3.0).g,
                  vc_lut(i0.b, 0.5 / 3.0).b);
    vec3 b = vec3(vc_lut(i0.r + 1.0, 0.5 / 3.0).r, vc_lut(i0.g + 1.0, 0.5 / 3.0).g,
                  vc_lut(i0.b + 1.0, 0.5 / 3.0).b);
    return a + (b - a) * (t - i0);
}

// The maps' texture coordinate of this output pixel. mpv's OUTPUT image is its video
// rectangle (HOOKED_size), not the window: bars outside it never reach the hook. With the
// filter that export-mpv prints (content scaled and padded to the grid in mpv, as
// viewcomp.rt.media.frames.fit_rect does) the video has the grid's aspect and this is
// HOOKED_pos. Without it, and with a window of the grid's aspect, the rectangle is where
// fit_rect places content of that aspect in the grid (centred, aspect kept): the maps are
// read there, so each pixel still gets its own correction (only the bars stay
// uncompensated).
vec2 vc_map_pos() {
    vec2 s = vec2(min(VC_GRID.x / HOOKED_size.x, VC_GRID.y / HOOKED_size.y));
    vec2 fit = clamp(floor(HOOKED_size * s + 0.5), vec2(1.0), VC_GRID);
    vec2 off = floor(0.5 * (VC_GRID - fit));
    return (off + HOOKED_pos * fit) / VC_GRID;
}
