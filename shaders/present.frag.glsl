#version 330 core
// The projector window of `viewcomp capture`: texel (x, y) of the pattern for window pixel
// (x, y), counted from the top (fullscreen.vert.glsl with u_flip_y = 1 hands over v_uv).
uniform sampler2D u_image;
in vec2 v_uv;
out vec4 f_color;
void main() {
    ivec2 size = textureSize(u_image, 0);
    ivec2 p = clamp(ivec2(v_uv * vec2(size)), ivec2(0), size - 1);
    f_color = vec4(texelFetch(u_image, p, 0).rgb, 1.0);
}
