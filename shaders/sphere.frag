#version 330
// Ray-cast the impostor's sphere: exact outline, normal and depth per pixel.
#include "lighting.glsl"
#include "sphere_hit.glsl"
in vec3 v_world;
in vec2 v_corner;
flat in vec3 v_centre;
flat in float v_radius;
flat in vec4 v_color;
out vec4 f_color;

void main() {
    vec3 hit = sphere_hit(u_eye, v_world, v_centre, v_radius);
    f_color = vec4(shade(v_color.rgb, (hit - v_centre) / v_radius, hit), v_color.a);
    gl_FragDepth = window_depth(hit);
}
