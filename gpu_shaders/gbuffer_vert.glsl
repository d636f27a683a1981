// G-buffer: world position, normals and material of the surface seen in each pixel.
in vec3 in_position;
in vec3 in_normal;
in vec3 in_albedo;
in vec3 in_emission;

uniform mat4 u_view_projection;

out vec3 v_world;
out vec3 v_normal;
out vec3 v_albedo;
out vec3 v_emission;

void main() {
    v_world = in_position;
    v_normal = in_normal;
    v_albedo = in_albedo;
    v_emission = in_emission;
    gl_Position = u_view_projection * vec4(in_position, 1.0);
}
