// G-buffer: world position, normals and material of the surface seen in each pixel. With
// TEXTURED a second vertex stream carries UVs and the texture attribute (core/geometry.py).
in vec3 in_position;
in vec3 in_normal;
in vec3 in_albedo;
in vec3 in_emission;

uniform mat4 u_view_projection;

out vec3 v_world;
out vec3 v_normal;
out vec3 v_albedo;
out vec3 v_emission;

#ifdef TEXTURED
in vec2 in_uv;
in vec3 in_texture;  // albedo layer, emission layer (-1 = none), emission strength
out vec2 v_uv;
flat out vec3 v_texture;
#endif

void main() {
    v_world = in_position;
    v_normal = in_normal;
    v_albedo = in_albedo;
    v_emission = in_emission;
#ifdef TEXTURED
    v_uv = in_uv;
    v_texture = in_texture;
#endif
    gl_Position = u_view_projection * vec4(in_position, 1.0);
}
