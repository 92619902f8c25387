// The per-pixel formula of docs/RUNTIME.md on values already fetched: the one GLSL source of
// it, included by the GL compensator (compensate.frag.glsl) and by the mpv export
// (mpv_hook.glsl). The numpy reference is viewcomp.calib.model.reference.compensate.
//
// Nothing here reads a texture, a uniform or a macro: the including file fetches the
// per-pixel values and passes the constants as arguments (literals in both hosts, which the
// compiler folds). What it must define is how the inverse LUT and the lobe table are read:
vec2 inv_pair(int c, int i);  // (inv_lut[i, c], inv_lut[i + 1, c]); at i = N - 1 the last twice
vec3 lobe_entry(int i);       // lobe[i] (RGB), i in 0..n - 1 (RuntimeModel.lobe)

// The pixel method's per-pixel values at one grid pixel: rows of Ww | Aw (w0..w2), rows of
// Wc | Ac (c0..c2), the unit reflection vector R | the camera's lobe (red), the surface
// point's x, y (metres; z = 0, the screen plane) | the camera's lobe (green, blue)
// (RuntimeModel.cam_lobe).
struct PixelMaps {
    vec4 w0, w1, w2, c0, c1, c2;
    vec4 refl;
    vec4 pos;
};

// The 8 texels of one pixel as stored (viewcomp.calib.model.shader_inputs.pixel_texels) -> PixelMaps.
PixelMaps pixel_maps(vec4 t0, vec4 t1, vec4 t2, vec4 t3, vec4 t4, vec4 t5, vec4 t6, vec4 t7) {
    PixelMaps m;
    m.w0 = t0;
    m.w1 = t1;
    m.w2 = t2;
    m.c0 = t3;
    m.c1 = t4;
    m.c2 = t5;
    m.refl = t6;
    m.pos = t7;
    return m;
}

// The lobe coordinate t = sqrt(1 - cos angle) of the surface point p seen from the eye
// (viewcomp.calib.model.lobe.lobe_position): the angle between N = +z and the half vector
// (half_angle), or between R and V.
float lobe_position(vec3 refl, vec3 p, vec3 eye, bool half_angle) {
    vec3 v = normalize(eye - p);
    float c;
    if (half_angle) {
        vec3 h = vec3(v.x - refl.x, v.y - refl.y, v.z + refl.z);  // Y + V, Y = R mirrored
        c = h.z / length(h);
    } else {
        c = dot(refl, v);
    }
    return sqrt(max(1.0 - c, 0.0));
}

// The lobe at t: linear interpolation in the n-entry table, ends held (lobe.lobe_lookup).
vec3 lobe_value(float t, int n) {
    float x = clamp(t, 0.0, 1.0) * float(n - 1);
    int i = min(int(x), n - 2);
    vec3 a = lobe_entry(i);
    return a + (lobe_entry(i + 1) - a) * (x - float(i));
}

// The specular ratio's change from the camera to the eye, per camera channel:
// ds = lobe(t_eye) - the camera's lobe (reference.lobe_change).
vec3 lobe_change(PixelMaps m, vec3 eye, bool half_angle, int n) {
    float t = lobe_position(m.refl.xyz, vec3(m.pos.xy, 0.0), eye, half_angle);
    return lobe_value(t, n) - vec3(m.refl.w, m.pos.z, m.pos.w);
}

// The screen's black level at the eye, Ac + ds (share Aw), share = the projector leak's
// part of the black level (reference.screen_at).
vec3 black_at(PixelMaps m, vec3 ds, vec3 share) {
    return vec3(m.c0.w, m.c1.w, m.c2.w) + ds * share * vec3(m.w0.w, m.w1.w, m.w2.w);
}

// The adjugate of M = Wc + diag(ds) Ww at the eye as columns k0, k1, k2 (M^-1 = [k0 k1 k2]
// / det); returns det.
float adjugate(PixelMaps m, vec3 ds, out vec3 k0, out vec3 k1, out vec3 k2) {
    vec3 r0 = m.c0.xyz + ds.x * m.w0.xyz;
    vec3 r1 = m.c1.xyz + ds.y * m.w1.xyz;
    vec3 r2 = m.c2.xyz + ds.z * m.w2.xyz;
    k0 = cross(r1, r2);
    k1 = cross(r2, r0);
    k2 = cross(r0, r1);
    return dot(r0, k0);
}

// Pixel method, solved: the projector light y with M y = alpha (Ww pw + Aw) + beta - A at
// the eye (unclamped; pw = the forward LUT of the frame's levels).
vec3 solve_pixel(PixelMaps m, vec3 pw, vec3 eye, float alpha, float beta, bool half_angle,
                 int n_lobe, vec3 share) {
    vec3 ds = lobe_change(m, eye, half_angle, n_lobe);
    vec3 cw = vec3(dot(m.w0.xyz, pw), dot(m.w1.xyz, pw), dot(m.w2.xyz, pw))
        + vec3(m.w0.w, m.w1.w, m.w2.w);
    vec3 b = alpha * cw + beta - black_at(m, ds, share);
    vec3 k0, k1, k2;
    float det = adjugate(m, ds, k0, k1, k2);
    return (k0 * b.x + k1 * b.y + k2 * b.z) / det;
}

// Pixel method: the inverse LUT's squared position t2 of y. The reference clamps y to
// [0, 1], then the position to [0, (N - 1)^2]; both maps are increasing, so that is one
// clamp with folded bounds: t2 = clamp(scale y - off, lo, hi)
// (viewcomp.calib.model.shader_inputs.inverse_position, on the CPU).
vec3 pixel_t2(vec3 y, vec3 scale, vec3 off, vec3 lo, vec3 hi) {
    return clamp(scale * y - off, lo, hi);
}

// The view cache of one pixel for a held eye (docs/RUNTIME.md): y = alpha (G pw + a) +
// beta b - d with G = M^-1 Ww, a = M^-1 Aw, b = M^-1 1, d = M^-1 A (A the black level at
// the eye), every row already scaled to t2 as pixel_t2 does (d also shifted by off). Out:
// rows i of (G | a) in g0..g2.
void view_terms(PixelMaps m, vec3 eye, bool half_angle, int n_lobe, vec3 share, vec3 scale,
                vec3 off, out vec4 g0, out vec4 g1, out vec4 g2, out vec3 b, out vec3 d) {
    vec3 ds = lobe_change(m, eye, half_angle, n_lobe);
    vec3 k0, k1, k2;
    float det = adjugate(m, ds, k0, k1, k2);
    vec3 s = scale / det;
    vec3 gc0 = (k0 * m.w0.x + k1 * m.w1.x + k2 * m.w2.x) * s;  // column 0 of G
    vec3 gc1 = (k0 * m.w0.y + k1 * m.w1.y + k2 * m.w2.y) * s;
    vec3 gc2 = (k0 * m.w0.z + k1 * m.w1.z + k2 * m.w2.z) * s;
    vec3 a = (k0 * m.w0.w + k1 * m.w1.w + k2 * m.w2.w) * s;
    b = (k0 + k1 + k2) * s;
    vec3 black = black_at(m, ds, share);
    d = (k0 * black.x + k1 * black.y + k2 * black.z) * s + off;
    g0 = vec4(gc0.x, gc1.x, gc2.x, a.x);
    g1 = vec4(gc0.y, gc1.y, gc2.y, a.y);
    g2 = vec4(gc0.z, gc1.z, gc2.z, a.z);
}

// An audience (docs/MODEL.md section 6): viewer k's share of the normal equations
// N y = S T - q of sum_k w_k |M_k y + A_k - T|^2 (reference.audience_normal):
// N += w M^T M, S += w M^T, q += w M^T A, with M and A the screen at the viewer's eye.
void audience_add(PixelMaps m, vec3 eye, float w, bool half_angle, int n_lobe, vec3 share,
                  inout mat3 nn, inout mat3 s, inout vec3 q) {
    vec3 ds = lobe_change(m, eye, half_angle, n_lobe);
    mat3 mt = mat3(m.c0.xyz + ds.x * m.w0.xyz, m.c1.xyz + ds.y * m.w1.xyz,
                   m.c2.xyz + ds.z * m.w2.xyz);  // columns = the rows of M: M^T
    nn += w * (mt * transpose(mt));
    s += w * mt;
    q += w * (mt * black_at(m, ds, share));
}

// An audience, solved: the projector light y = N^-1 (S (alpha (Ww pw + Aw) + beta) - q)
// (unclamped; reference.target_to_projector).
vec3 solve_audience(mat3 nn, mat3 s, vec3 q, PixelMaps m, vec3 pw, float alpha, float beta) {
    vec3 cw = vec3(dot(m.w0.xyz, pw), dot(m.w1.xyz, pw), dot(m.w2.xyz, pw))
        + vec3(m.w0.w, m.w1.w, m.w2.w);
    return inverse(nn) * (s * (alpha * cw + beta) - q);
}

// The view cache of one pixel for a held audience: view_terms with P = N^-1 S in place of
// M^-1 and d = N^-1 q in place of M^-1 A (reference.audience_solve), scaled and shifted as
// view_terms does.
void audience_view_terms(mat3 nn, mat3 s, vec3 q, PixelMaps m, vec3 scale, vec3 off,
                         out vec4 g0, out vec4 g1, out vec4 g2, out vec3 b, out vec3 d) {
    mat3 n_inv = inverse(nn);
    mat3 p = n_inv * s;
    mat3 g = p * transpose(mat3(m.w0.xyz, m.w1.xyz, m.w2.xyz));  // G = P Ww; g[j] = column j
    vec3 a = p * vec3(m.w0.w, m.w1.w, m.w2.w);
    b = (p[0] + p[1] + p[2]) * scale;
    d = (n_inv * q) * scale + off;
    g0 = vec4(g[0].x, g[1].x, g[2].x, a.x) * scale.x;
    g1 = vec4(g[0].y, g[1].y, g[2].y, a.y) * scale.y;
    g2 = vec4(g[0].z, g[1].z, g[2].z, a.z) * scale.z;
}

// Pixel method from the view cache: t2 (unclamped) of the frame's pw.
vec3 cached_t2(vec4 g0, vec4 g1, vec4 g2, vec3 b, vec3 d, vec3 pw, float alpha, float beta) {
    vec3 gp = vec3(dot(g0.xyz, pw), dot(g1.xyz, pw), dot(g2.xyz, pw)) + vec3(g0.w, g1.w, g2.w);
    return alpha * gp + beta * b - d;
}

// Paper method: t2 = A pw + c with row i of A | c in a_i, folded on the CPU from alpha,
// beta, Ww, Wc_inv and the LUT domain (viewcomp.calib.model.shader_inputs.paper_rows), clamped to
// [0, top] with top = (N - 1)^2.
vec3 paper_t2(vec4 a0, vec4 a1, vec4 a2, vec3 pw, float top) {
    vec3 t2 = vec3(dot(a0.xyz, pw), dot(a1.xyz, pw), dot(a2.xyz, pw)) + vec3(a0.w, a1.w, a2.w);
    return clamp(t2, 0.0, top);
}

// ---- The adaptive tone map (viewcomp.calib.model.gamut; docs/RUNTIME.md "Adaptive tone map").
// Its constants come as gk = (KNEE, TINY, SHARE_MAX) and limit = GREY_LIMIT
// (viewcomp.calib.model.shader_inputs.gamut_constants).

// The adaptive tone map's field at grid pixel p is bilinear between the nx x ny nodes, node 0
// on the first pixel's centre and node n - 1 on the last's (gamut.node_weights,
// gamut.field_at). field_cell: the indices (nx row + column) of the four nodes around p,
// (z00, z01, z10, z11), and the weights f; step = (nx - 1) / (W - 1), (ny - 1) / (H - 1) as
// float32. The including file fetches the nodes' (gain, offset) and calls field_blend.
ivec4 field_cell(ivec2 p, int nx, int ny, vec2 step, out vec2 f) {
    vec2 x = vec2(p) * step;
    ivec2 i0 = min(ivec2(x), ivec2(max(nx - 2, 0), max(ny - 2, 0)));
    f = x - vec2(i0);
    ivec2 i1 = min(i0 + 1, ivec2(nx - 1, ny - 1));
    return ivec4(i0.y * nx + i0.x, i0.y * nx + i1.x, i1.y * nx + i0.x, i1.y * nx + i1.x);
}

// The same from the rows of nodes already interpolated along x at this pixel's column
// (top: row i0.y, bot: row i1.y; shader_inputs.field_columns): the blend along y.
// field_rows: those two rows' indices and the weight f.y of the second.
ivec2 field_rows(int py, int ny, float step_y, out float fy) {
    float y = float(py) * step_y;
    int i0 = min(int(y), max(ny - 2, 0));
    fy = y - float(i0);
    return ivec2(i0, min(i0 + 1, ny - 1));
}

vec2 field_blend(vec2 z00, vec2 z01, vec2 z10, vec2 z11, vec2 f) {
    vec2 top = z00 + (z01 - z00) * f.x;
    vec2 bot = z10 + (z11 - z10) * f.x;
    return top + (bot - top) * f.y;
}

// The greys n (1, 1, 1) a pixel can show, n v + c in [0, 1]^3: (n_lo, n_hi), n_lo > n_hi
// when none (gamut.grey_range). A channel with v = 0 bounds nothing.
vec2 grey_range(vec3 v, vec3 c, float tiny, float limit) {
    bvec3 live = greaterThan(abs(v), vec3(tiny));
    vec3 safe = mix(vec3(1.0), v, live);
    vec3 a = -c / safe;
    vec3 b = (1.0 - c) / safe;
    vec3 lo = mix(vec3(-limit), min(a, b), live);
    vec3 hi = mix(vec3(limit), max(a, b), live);
    return clamp(vec2(max(max(lo.x, lo.y), lo.z), min(min(hi.x, hi.y), hi.z)), -limit, limit);
}

// The rational knee over the top r of a range ending at hi: x unchanged below hi - r,
// tending to hi above it; e.g. the chroma's share knee_top(1, t_max, kn t_max).
float knee_top(float x, float hi, float r) {
    float up = max(x - (hi - r), 0.0);
    return x - up + up * r / (r + up);
}

// x pressed into [lo, hi]: the knee over the top kn of the range, held at lo below it
// (gamut.knee).
float knee(float x, float lo, float hi, float kn, float tiny) {
    return max(knee_top(x, hi, kn * max(hi - lo, tiny)), lo);
}

// The adaptive tone map's projector light (gamut.soft_light): the target g C_w + o asks for
// g u + o v + c; its luminance (k . C_w = luma_cw) is pressed under the grey range's top by
// the knee, chromaticity kept, then its chroma toward that grey by the knee on the share that
// fits; a target below the range (or where no grey fits) is clipped per channel. The result
// is hue x that + (1 - hue) x the light asked for clipped per channel. go = (g, o)
// (field_blend), range = grey_range(v, c). top: the light's full scale per channel, 1, or s
// when u, v, c come scaled by s (the view cache's terms, s = SQ_SCALE: the share is a ratio,
// the same in either unit, and the result is s y, clamped to [0, s]).
vec3 soft_light(vec3 u, vec3 v, vec3 c, float luma_cw, vec2 go, vec2 range, vec3 gk, vec3 top,
                float hue) {
    vec3 asked = clamp(go.x * u + go.y * v + c, vec3(0.0), top);
    if (hue <= 0.0) return asked;  // the per-channel clip alone (hue: one per draw)
    float lum = go.x * luma_cw + go.y;
    bool ok = range.x <= range.y && lum >= range.x;
    float lum2 = ok ? knee(lum, range.x, range.y, gk.x, gk.y) : lum;
    bool lit = lum > gk.y;
    float ratio = lit ? lum2 / lum : 0.0;
    vec3 grey = lum2 * v + c;
    vec3 chroma = lit ? (ratio * go.x) * u + (ratio * go.y - lum2) * v : vec3(0.0);
    vec3 room = mix(-grey, top - grey, greaterThan(chroma, vec3(0.0)));
    vec3 share = mix(vec3(gk.z), room / chroma, greaterThan(abs(chroma), gk.y * top));
    float t_max = clamp(min(min(share.x, share.y), share.z), 0.0, gk.z);
    float t = ok ? knee_top(1.0, t_max, gk.x * max(t_max, gk.y)) : 1.0;
    vec3 soft = clamp(grey + t * chroma, vec3(0.0), top);
    return hue >= 1.0 ? soft : mix(asked, soft, hue);
}

// Linear interpolation in the inverse LUT (reference.lut_inverse) at the squared position
// t2 in [0, (N - 1)^2]: the LUT is sampled uniformly in the square root of the normalised
// value, so the position is t = sqrt(t2). t >= 0 truncates to its floor, and at t = N - 1
// the last pair (inv_lut[N - 1] twice) applies. Returns 0..1.
vec3 lut_inverse_sq(vec3 t2) {
    vec3 t = sqrt(t2);
    ivec3 i0 = ivec3(t);
    vec3 f = t - vec3(i0);
    vec2 ab0 = inv_pair(0, i0.x);
    vec2 ab1 = inv_pair(1, i0.y);
    vec2 ab2 = inv_pair(2, i0.z);
    vec3 a = vec3(ab0.x, ab1.x, ab2.x);
    vec3 b = vec3(ab0.y, ab1.y, ab2.y);
    return a + (b - a) * f;
}

// The output level: roundEven(255 clamp(out, 0, 1)) (= np.rint) as level / 255, which any
// float -> unorm8 conversion returns exactly as that level.
vec3 quantise(vec3 result) {
    return roundEven(clamp(result, 0.0, 1.0) * 255.0) / 255.0;
}
