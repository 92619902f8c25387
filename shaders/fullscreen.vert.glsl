#version 330 core
// A triangle that covers the whole viewport, from gl_VertexID alone (draw 3 vertices, no
// vertex buffer). It hands the fragment shader
// - v_uv: the texture coordinate of the grid, so that the fragment at viewport pixel (x, y)
//   gets the centre of texel (x, y) ((x, H - 1 - y) with u_flip_y = 1, for a window whose
//   y = 0 is the bottom); the viewport places and sizes the grid.
// - v_frame[4]: the per-frame values (eye, tone map, the paper method's folded matrices),
//   flat. Fragment shaders on llvmpipe pay for every uniform component they read, per pixel;
//   flat inputs cost a fraction of that, so per-frame uniforms are read here, three times.

uniform int u_flip_y;
uniform vec4 u_frame[4];

out vec2 v_uv;
flat out vec4 v_frame[4];

void main() {
    vec2 p = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));  // (0,0) (2,0) (0,2)
    gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
    v_uv = vec2(p.x, u_flip_y != 0 ? 1.0 - p.y : p.y);
    for (int i = 0; i < 4; i++) {
        v_frame[i] = u_frame[i];
    }
}
