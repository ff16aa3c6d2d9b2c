#version 330
// The square of ground the shadow map covers, as two triangles on y = 0.
in vec2 in_corner;              // -1..1
uniform mat4 u_view_proj;
uniform vec3 u_shadow_region;   // centre x, centre z, half extent (metres)
out vec2 v_uv;

void main() {
    v_uv = in_corner * 0.5 + 0.5;
    vec2 xz = u_shadow_region.xy + in_corner * u_shadow_region.z;
    gl_Position = u_view_proj * vec4(xz.x, 0.0, xz.y, 1.0);
}
