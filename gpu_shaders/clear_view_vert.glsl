// The clear triangles (WorldGeometry.clear_triangles) seen from the camera: each fragment is
// the light one crossing of the surface lets through towards the camera (clear_view_frag).
in vec3 in_position;
in vec3 in_normal;          // the triangle's unit normal
in vec4 in_transmission;    // colour let through, Fresnel IOR (0: no Fresnel loss)

uniform mat4 u_view_projection;

out vec3 v_world;
flat out vec3 v_normal;
flat out vec4 v_transmission;

void main() {
    v_world = in_position;
    v_normal = in_normal;
    v_transmission = in_transmission;
    gl_Position = u_view_projection * vec4(in_position, 1.0);
}
