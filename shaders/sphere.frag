#version 330
// Ray-cast the impostor's sphere: exact outline, normal and depth per pixel.
#include "lighting.glsl"
uniform vec4 u_clip_z;   // rows 2 and 3 of the view-projection matrix
uniform vec4 u_clip_w;
in vec3 v_world;
in vec2 v_corner;
flat in vec3 v_centre;
flat in float v_radius;
flat in vec4 v_color;
out vec4 f_color;

void main() {
    vec3 dir = normalize(v_world - u_eye);
    vec3 oc = u_eye - v_centre;
    float b = dot(oc, dir);
    float h = b * b - dot(oc, oc) + v_radius * v_radius;
    if (h < 0.0) discard;
    vec3 hit = u_eye + (-b - sqrt(h)) * dir;
    f_color = vec4(shade(v_color.rgb, (hit - v_centre) / v_radius, hit), v_color.a);
    gl_FragDepth = 0.5 + 0.5 * (dot(u_clip_z.xyz, hit) + u_clip_z.w) / (dot(u_clip_w.xyz, hit) + u_clip_w.w);
}
