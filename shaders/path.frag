#version 330
uniform float u_dash_length;   // metres per dash + gap
in vec4 v_color;
in float v_arc;
in float v_across;
flat in float v_dashed;
out vec4 f_color;

void main() {
    if (v_dashed > 0.5 && fract(v_arc / u_dash_length) > 0.55) discard;
    // Soft edges across the ribbon stand in for anti-aliasing.
    float edge = 1.0 - smoothstep(0.6, 1.0, abs(v_across));
    f_color = vec4(sqrt(v_color.rgb), v_color.a * edge);
}
