#version 330
// A polyline segment as a screen-space ribbon of constant pixel width (GL core has no wide lines).
in vec2 in_corner;      // x: 0 at p0, 1 at p1; y: -1 or +1 across the ribbon
in vec3 i_p0;
in vec3 i_p1;
in vec2 i_arc;          // arc length (metres) at p0 and p1, for dashes
in vec4 i_color;        // linear rgba
in vec2 i_style;        // width in pixels, dashed (0 or 1)
uniform mat4 u_view_proj;
uniform vec2 u_viewport;   // screen pixels, the unit of the widths
out vec4 v_color;
out float v_arc;
out float v_across;
flat out float v_dashed;

void main() {
    vec4 c0 = u_view_proj * vec4(i_p0, 1.0);
    vec4 c1 = u_view_proj * vec4(i_p1, 1.0);
    v_color = i_color;
    v_arc = mix(i_arc.x, i_arc.y, in_corner.x);
    v_across = in_corner.y;
    v_dashed = i_style.y;
    if (c0.w < 1e-3 || c1.w < 1e-3) {   // behind the camera: drop the segment
        gl_Position = vec4(2.0, 2.0, 2.0, 1.0);
        return;
    }
    vec2 half_px = 0.5 * u_viewport;
    vec2 d = c1.xy / c1.w * half_px - c0.xy / c0.w * half_px;
    d = length(d) > 1e-4 ? normalize(d) : vec2(1.0, 0.0);
    vec2 across = vec2(-d.y, d.x);
    vec4 c = in_corner.x < 0.5 ? c0 : c1;
    // Widen by half the width along the segment too, so consecutive segments overlap at joins.
    vec2 offset_px = 0.5 * i_style.x * (across * in_corner.y + d * (2.0 * in_corner.x - 1.0));
    c.xy += offset_px / half_px * c.w;
    c.z -= 2e-4 * c.w;   // stay in front of the surface a path lies on
    gl_Position = c;
}
