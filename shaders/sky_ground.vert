#version 330
// A screen-covering triangle that carries each corner's view ray (near and far points in
// homogeneous world coordinates) so the fragment shader needs no matrix per pixel.
uniform mat4 u_inv_view_proj;
out vec4 v_near;
out vec4 v_far;

void main() {
    vec2 p = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2)) * 2.0 - 1.0;
    v_near = u_inv_view_proj * vec4(p, -1.0, 1.0);
    v_far = u_inv_view_proj * vec4(p, 1.0, 1.0);
    gl_Position = vec4(p, 0.0, 1.0);
}
