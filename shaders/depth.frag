#version 330
// Depth only (the keyframe ghosts' pre-pass): the rasterizer writes depth; the colour written
// here is blended away (see SceneRenderer._draw_overlays).
out vec4 f_color;

void main() {
    f_color = vec4(0.0);
}
