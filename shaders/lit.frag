#version 330
// Shaded triangle surfaces: capsules and object meshes.
#include "lighting.glsl"
in vec3 v_world;
in vec3 v_normal;
in vec4 v_color;
out vec4 f_color;

void main() {
    f_color = vec4(shade(v_color.rgb, normalize(v_normal), v_world), v_color.a);
}
