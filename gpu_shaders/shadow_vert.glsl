// Shadow-map rendering: one tile (a cube face or a directional map) of the atlas per draw.
#include "common_lib.glsl"

in vec3 in_position;

uniform vec3 u_origin;   // light position, or the direction of travel for directional lights
uniform int u_face;      // 0..5 cube face, -1 for a directional map
uniform float u_near;
uniform float u_far;
uniform vec3 u_scene_centre;
uniform float u_scene_radius;

out vec3 v_world;

void main() {
    v_world = in_position;
    if (u_face >= 0) {
        gl_Position = cube_face_clip(in_position, u_origin, u_face, u_near, u_far);
    } else {
        gl_Position = directional_clip(in_position, u_origin, u_scene_centre, u_scene_radius);
    }
}
