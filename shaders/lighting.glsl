// Soft studio lighting shared by the lit surfaces (included, not compiled on its own):
// sky/ground hemisphere ambient, a wrapped key light, a cool fill, a faint specular and a rim
// that lifts silhouettes off the background.
// Colours are linear; output gamma is 2 (sqrt is cheap in software GL, pow is not).
uniform vec3 u_eye;
uniform vec3 u_light_dir;   // unit, towards the key light

vec3 shade(vec3 base, vec3 n, vec3 world) {
    vec3 view = normalize(u_eye - world);
    float hemi = 0.5 + 0.5 * n.y;
    vec3 ambient = mix(vec3(0.22, 0.20, 0.18), vec3(0.42, 0.46, 0.52), hemi);
    float key = max((dot(n, u_light_dir) + 0.25) / 1.25, 0.0);
    vec3 fill_dir = normalize(vec3(-u_light_dir.x, 0.2, -u_light_dir.z));
    float fill = max(dot(n, fill_dir), 0.0);
    vec3 h = normalize(u_light_dir + view);
    float spec = max(dot(n, h), 0.0);
    spec *= spec; spec *= spec; spec *= spec; spec *= spec; spec *= spec;   // ^32
    float edge = 1.0 - max(dot(n, view), 0.0);
    float rim = edge * edge * edge;
    // Darken towards the floor: cheap contact occlusion for feet and low objects.
    float occlusion = mix(0.65, 1.0, smoothstep(0.0, 0.35, world.y));
    vec3 c = base * (ambient + 0.95 * key * vec3(1.0, 0.96, 0.9) + 0.18 * fill * vec3(0.8, 0.9, 1.0)) * occlusion
           + 0.12 * spec + 0.18 * rim * hemi * vec3(0.9, 0.95, 1.0);
    return sqrt(c);
}
