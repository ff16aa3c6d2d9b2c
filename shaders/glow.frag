#version 330
// A bright core and a Gaussian halo, added onto what is behind.
in vec2 v_corner;
in vec4 v_color;
out vec4 f_color;

void main() {
    float r2 = dot(v_corner, v_corner);
    float glow = exp(-r2 * 5.0) * 0.65 + smoothstep(0.16, 0.12, r2) * 0.4;
    f_color = vec4(sqrt(v_color.rgb) * glow * v_color.a, 1.0);
}
