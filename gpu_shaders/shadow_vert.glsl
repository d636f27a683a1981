// Shadow-map rendering: every atlas tile (a cube face or a directional map) in one instanced
// draw (see tiles_lib.glsl).
#include "tiles_lib.glsl"

in vec3 in_position;

out vec3 v_world;
flat out vec3 v_origin;
flat out int v_face;

void main() {
    gl_Position = atlas_tile_position(in_position, gl_InstanceID, v_origin, v_face);
    v_world = in_position;
}
