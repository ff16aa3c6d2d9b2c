#version 330
// Sky gradient and an infinite ground plane (y = 0) with a metre grid, ray-cast per pixel so
// the ground needs no geometry and fades into the horizon haze. It depends on the camera only,
// so the renderer caches its result between camera moves. Colours are linear; output gamma is 2.
uniform vec4 u_clip_z;          // rows 2 and 3 of the view-projection matrix: depth of a
uniform vec4 u_clip_w;          // ground point without a matrix product
uniform vec3 u_ground_color;
uniform vec3 u_horizon_color;
uniform vec3 u_zenith_color;
uniform float u_haze_distance;
in vec4 v_near;
in vec4 v_far;
out vec4 f_color;

void main() {
    vec3 origin = v_near.xyz / v_near.w;
    vec3 ray = v_far.xyz / v_far.w - origin;
    if (ray.y >= 0.0 || origin.y <= 0.0) {
        float up = clamp(ray.y * inversesqrt(dot(ray, ray)) / 0.6, 0.0, 1.0);
        f_color = vec4(sqrt(mix(u_horizon_color, u_zenith_color, up)), 1.0);
        gl_FragDepth = 1.0;
        return;
    }
    float t = -origin.y / ray.y;
    vec3 p = origin + t * ray;

    // Grid lines every 0.25 m (faint) and 1 m, about a pixel wide, faded where they would alias.
    vec2 q = p.xz * 4.0;
    vec2 w = max(fwidth(q), vec2(1e-5));
    vec2 minor = abs(fract(q - 0.5) - 0.5) / w;
    vec2 major = abs(fract(q * 0.25 - 0.5) - 0.5) / (w * 0.25);
    float fade = 1.0 - smoothstep(0.6, 1.8, max(w.x, w.y));
    float lines = 0.10 * (1.0 - clamp(min(minor.x, minor.y), 0.0, 1.0)) * fade
                + 0.22 * (1.0 - clamp(min(major.x, major.y) - 0.2, 0.0, 1.0)) * (1.0 - smoothstep(2.4, 7.2, max(w.x, w.y)));
    vec3 color = u_ground_color * (1.0 - lines);

    float haze = 1.0 - exp(-t * length(ray) / u_haze_distance);
    f_color = vec4(sqrt(mix(color, u_horizon_color, haze)), 1.0);
    gl_FragDepth = min(0.5 + 0.5 * (dot(u_clip_z.xyz, p) + u_clip_z.w) / (dot(u_clip_w.xyz, p) + u_clip_w.w), 1.0);
}
