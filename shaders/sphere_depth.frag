#version 330
// Depth only (the keyframe ghosts' pre-pass): the impostor's outline and depth, no shading;
// the colour written here is blended away (see SceneRenderer._draw_overlays).
#include "sphere_hit.glsl"
uniform vec3 u_eye;
in vec3 v_world;
flat in vec3 v_centre;
flat in float v_radius;
out vec4 f_color;

void main() {
    gl_FragDepth = window_depth(sphere_hit(u_eye, v_world, v_centre, v_radius));
    f_color = vec4(0.0);
}
