#version 330
// Darkens the ground under the shadow map; blended as a multiply onto the gamma-2 image,
// so the factor is the square root of the linear one.
uniform sampler2D u_shadow;
uniform float u_shadow_strength;
in vec2 v_uv;
out vec4 f_color;

void main() {
    f_color = vec4(sqrt(1.0 - u_shadow_strength * texture(u_shadow, v_uv).r));
}
