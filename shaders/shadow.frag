#version 330
// Shadow-map pass: occluders flattened onto the ground along the light write how dark they
// make it there (blended with MAX); higher parts cast lighter shadows.
uniform float u_fade_height;
in vec3 v_world;
out vec4 f_color;

void main() {
    f_color = vec4(clamp(1.0 - v_world.y / u_fade_height, 0.25, 1.0));
}
