// Stores the occluder's distance: radial from the light (cube faces) or along the axis.
#include "common_lib.glsl"

in vec3 v_world;
flat in vec3 v_origin;
flat in int v_face;

uniform vec3 u_scene_centre;
uniform float u_scene_radius;

out float out_distance;

void main() {
    out_distance = v_face >= 0 ? length(v_world - v_origin)
                               : directional_depth(v_world, v_origin, u_scene_centre,
                                                   u_scene_radius);
}
