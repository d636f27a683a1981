// Stores the occluder's distance: radial from the light (cube faces) or along the axis.
#include "common_lib.glsl"

in vec3 v_world;

uniform vec3 u_origin;
uniform int u_face;
uniform vec3 u_scene_centre;
uniform float u_scene_radius;

out float out_distance;

void main() {
    out_distance = u_face >= 0 ? length(v_world - u_origin)
                               : directional_depth(v_world, u_origin, u_scene_centre,
                                                   u_scene_radius);
}
