// Reflective shadow maps: the surfaces each light sees, in the same atlas tiles as shadow maps.
#include "tiles_lib.glsl"

in vec3 in_position;

out vec3 v_world;
flat out int v_triangle;
flat out vec3 v_origin;
flat out int v_face;

void main() {
    gl_Position = atlas_tile_position(in_position, gl_InstanceID, v_origin, v_face);
    v_world = in_position;
    v_triangle = gl_VertexID / 3;
}
