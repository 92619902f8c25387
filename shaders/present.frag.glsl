#version 330 core
// Shows an image texture over the viewport (with fullscreen.vert.glsl): the projector window
// of `viewcomp capture` (texture filter NEAREST: texel for window pixel, pixel for pixel) and
// the player's grid -> window pass (NEAREST or LINEAR, set on the texture).
uniform sampler2D u_image;
in vec2 v_uv;
out vec4 frag_color;
void main() {
    frag_color = vec4(texture(u_image, v_uv).rgb, 1.0);
}
