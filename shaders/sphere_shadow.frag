#version 330
// Shadow-map pass for sphere impostors: the disc, as dark as shadow.frag makes its height.
uniform float u_fade_height;
in vec2 v_corner;
flat in vec3 v_centre;
out vec4 f_color;

void main() {
    if (dot(v_corner, v_corner) > 1.0) discard;
    f_color = vec4(clamp(1.0 - v_centre.y / u_fade_height, 0.25, 1.0));
}
