// A shadow atlas's clear layer: per texel, the light the clear surfaces in front of its opaque
// occluder let through towards the light (rgb: each colour × (1 − F) at the light's angle,
// multiplied by blending) and the nearest one's distance (a, kept by MIN blending), in the
// opaque layer's measure (shadow_frag.glsl). A receiver beyond that distance gets rgb.
#include "common_lib.glsl"
#include "fresnel_lib.glsl"

in vec3 v_world;
flat in vec3 v_origin;      // the light's position (cube faces) or axis (directional)
flat in int v_face;
flat in vec3 v_normal;
flat in vec4 v_transmission;

uniform vec3 u_scene_centre;
uniform float u_scene_radius;

out vec4 out_clear;

void main() {
    vec3 dir = v_face >= 0 ? v_world - v_origin : v_origin;
    float cos_i = abs(dot(v_normal, dir)) / max(length(dir), 1.0e-30);
    vec3 colour = clear_crossing(v_transmission.rgb, v_transmission.a, cos_i);
    float distance = v_face >= 0 ? length(v_world - v_origin)
                                 : directional_depth(v_world, v_origin, u_scene_centre,
                                                     u_scene_radius);
    out_clear = vec4(colour, distance);
}
