#version 330 core
// A triangle that covers the whole viewport, from gl_VertexID alone (draw 3 vertices, no
// vertex buffer). The fragment shader addresses texels with gl_FragCoord, so no varyings.

void main() {
    vec2 p = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));  // (0,0) (2,0) (0,2)
    gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}
