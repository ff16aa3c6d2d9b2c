#version 330
// Darkens the ground under the shadow map; blended as a multiply onto the gamma-2 image,
// so the factor is the square root of the linear one. Some of the unblurred map is added to
// the blurred one, so contact shadows under feet stay crisp inside the soft ones.
uniform sampler2D u_soft;
uniform sampler2D u_sharp;
uniform float u_shadow_strength;
in vec2 v_uv;
out vec4 f_color;

void main() {
    float shadow = min(1.0, 0.85 * texture(u_soft, v_uv).r + 0.3 * texture(u_sharp, v_uv).r);
    f_color = vec4(sqrt(1.0 - u_shadow_strength * shadow));
}
