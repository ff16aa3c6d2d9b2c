#version 330
// Lays a cached layer over the scene: its premultiplied colour at its own depth, so the depth
// test still hides it behind nearer bodies and the ground.
uniform sampler2D u_color;
uniform sampler2D u_depth;
out vec4 f_color;

void main() {
    ivec2 pixel = ivec2(gl_FragCoord.xy);
    f_color = texelFetch(u_color, pixel, 0);
    if (f_color.a == 0.0) discard;
    gl_FragDepth = texelFetch(u_depth, pixel, 0).r;
}
