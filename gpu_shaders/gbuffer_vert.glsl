// G-buffer: world position, normals and material of the surface seen in each pixel. The
// material comes from the triangle's row of the material table (materials_lib.glsl); with
// TEXTURED a second vertex stream carries UVs.
in vec3 in_position;
in vec3 in_normal;

uniform mat4 u_view_projection;

out vec3 v_world;
out vec3 v_normal;
flat out int v_triangle;

#ifdef TEXTURED
in vec2 in_uv;
out vec2 v_uv;
#endif

void main() {
    v_world = in_position;
    v_normal = in_normal;
    v_triangle = gl_VertexID / 3;
#ifdef TEXTURED
    v_uv = in_uv;
#endif
    gl_Position = u_view_projection * vec4(in_position, 1.0);
}
