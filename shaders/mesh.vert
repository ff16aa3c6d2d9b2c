#version 330
// A rigid object mesh under its pose.
in vec3 in_position;
in vec3 in_normal;
uniform mat4 u_model;
uniform mat4 u_view_proj;
uniform vec4 u_color;   // linear rgba
out vec3 v_world;
out vec3 v_normal;
out vec4 v_color;

void main() {
    v_world = (u_model * vec4(in_position, 1.0)).xyz;
    v_normal = mat3(u_model) * in_normal;
    v_color = u_color;
    gl_Position = u_view_proj * vec4(v_world, 1.0);
}
