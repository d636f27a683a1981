// The clear triangles (WorldGeometry.clear_triangles) into every tile of a shadow atlas, as
// shadow_vert.glsl draws the opaque ones (see shadow_clear_frag.glsl).
#include "tiles_lib.glsl"

in vec3 in_position;
in vec3 in_normal;          // the triangle's unit normal
in vec4 in_transmission;    // colour let through, Fresnel IOR (0: no Fresnel loss)

out vec3 v_world;
flat out vec3 v_origin;
flat out int v_face;
flat out vec3 v_normal;
flat out vec4 v_transmission;

void main() {
    gl_Position = atlas_tile_position(in_position, gl_InstanceID, v_origin, v_face);
    v_world = in_position;
    v_normal = in_normal;
    v_transmission = in_transmission;
}
