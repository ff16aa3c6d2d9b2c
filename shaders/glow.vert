#version 330
// A camera-facing quad per contact highlight, pulled towards the camera so the hand cannot hide it.
in vec2 in_corner;      // -1..1
in vec3 i_centre;
in float i_radius;
in vec4 i_color;        // linear rgba
uniform mat4 u_view;
uniform mat4 u_proj;
out vec2 v_corner;
out vec4 v_color;

void main() {
    vec4 p = u_view * vec4(i_centre, 1.0);
    p.z += i_radius;
    p.xy += in_corner * i_radius * 2.6;
    v_corner = in_corner;
    v_color = i_color;
    gl_Position = u_proj * p;
}
