#version 330
// A tapered cylinder from i_a to i_b per instance, built around a unit ring mesh
// (in_ring = cos, sin, t along the axis). Spheres at the joints cap the ends.
in vec3 in_ring;
in vec3 i_a;
in vec3 i_b;
in vec2 i_radius;   // at a, at b
in vec4 i_color;    // linear rgba
uniform mat4 u_view_proj;
out vec3 v_world;
out vec3 v_normal;
out vec4 v_color;

void main() {
    vec3 axis = i_b - i_a;
    float len = max(length(axis), 1e-5);
    vec3 w = axis / len;
    vec3 helper = abs(w.y) < 0.99 ? vec3(0.0, 1.0, 0.0) : vec3(1.0, 0.0, 0.0);
    vec3 u = normalize(cross(helper, w));
    vec3 v = cross(w, u);
    vec3 radial = in_ring.x * u + in_ring.y * v;
    float r = mix(i_radius.x, i_radius.y, in_ring.z);
    v_world = mix(i_a, i_b, in_ring.z) + r * radial;
    // A cone's surface normal leans back along the axis by the taper slope.
    v_normal = normalize(radial - w * (i_radius.y - i_radius.x) / len);
    v_color = i_color;
    gl_Position = u_view_proj * vec4(v_world, 1.0);
}
