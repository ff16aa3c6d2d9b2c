#version 330
// One direction of a separable 9-tap Gaussian blur of the shadow map.
uniform sampler2D u_source;
uniform vec2 u_step;          // texel offset per tap, in uv
in vec2 v_ndc;
out vec4 f_color;

void main() {
    vec2 uv = v_ndc * 0.5 + 0.5;
    const float weight[5] = float[](0.227027, 0.1945946, 0.1216216, 0.054054, 0.016216);
    float sum = texture(u_source, uv).r * weight[0];
    for (int i = 1; i < 5; ++i) {
        sum += texture(u_source, uv + u_step * float(i)).r * weight[i];
        sum += texture(u_source, uv - u_step * float(i)).r * weight[i];
    }
    f_color = vec4(sum);
}
