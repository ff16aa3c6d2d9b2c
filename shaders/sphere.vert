#version 330
// Spheres (joints, hands, head) as ray-cast impostors: one quad per sphere facing u_eye, which
// costs two triangles instead of hundreds (software GL pays per triangle).
in vec2 in_corner;      // -1..1
in vec3 i_centre;
in float i_radius;
in vec4 i_color;        // linear rgba
uniform mat4 u_view_proj;
uniform vec3 u_eye;     // the camera, or a point far along the light for the shadow pass
out vec3 v_world;
out vec2 v_corner;
flat out vec3 v_centre;
flat out float v_radius;
flat out vec4 v_color;

const float MARGIN = 1.15;  // the outline of a sphere seen up close is a bit wider than r

void main() {
    vec3 w = normalize(u_eye - i_centre);
    vec3 helper = abs(w.y) < 0.99 ? vec3(0.0, 1.0, 0.0) : vec3(1.0, 0.0, 0.0);
    vec3 u = normalize(cross(helper, w));
    vec3 v = cross(w, u);
    v_corner = in_corner * MARGIN;
    v_world = i_centre + i_radius * (v_corner.x * u + v_corner.y * v);
    v_centre = i_centre;
    v_radius = i_radius;
    v_color = i_color;
    gl_Position = u_view_proj * vec4(v_world, 1.0);
}
