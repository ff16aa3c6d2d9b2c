// Ray-casting sphere impostors (included by the sphere fragment shaders, not compiled alone).
uniform vec4 u_clip_z;   // rows 2 and 3 of the view-projection matrix
uniform vec4 u_clip_w;

// Where the ray from `eye` through `through` first meets the sphere; the pixel is discarded
// where it misses.
vec3 sphere_hit(vec3 eye, vec3 through, vec3 centre, float radius) {
    vec3 dir = normalize(through - eye);
    vec3 oc = eye - centre;
    float b = dot(oc, dir);
    float h = b * b - dot(oc, oc) + radius * radius;
    if (h < 0.0) discard;
    return eye + (-b - sqrt(h)) * dir;
}

// The window depth (0..1) of a world point.
float window_depth(vec3 p) {
    return 0.5 + 0.5 * (dot(u_clip_z.xyz, p) + u_clip_z.w) / (dot(u_clip_w.xyz, p) + u_clip_w.w);
}
