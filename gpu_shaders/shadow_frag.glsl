// Stores the occluder's distance: radial from the light (cube faces) or along the axis. With
// SHADOWLESS, triangles of objects that cast no shadow (geometry.SHADOWLESS) are left out
// (lights' maps), with DIFFUSE_HIDDEN those diffuse bounces pass (geometry.DIFFUSE_HIDDEN:
// VPLs' maps); with CUTOUTS, a cutout's texels are kept with probability its coverage
// (cutout_lib.glsl).
#include "common_lib.glsl"
#include "cutout_lib.glsl"

in vec3 v_world;
flat in vec3 v_origin;
flat in int v_face;

uniform vec3 u_scene_centre;
uniform float u_scene_radius;

out float out_distance;

void main() {
#ifdef SHADOWLESS
    if (material_of(v_triangle).texture.w > 0.5) discard;
#endif
#ifdef DIFFUSE_HIDDEN
    if (material_of(v_triangle).cutout.w > 0.5) discard;
#endif
    if (!cutout_kept()) discard;
    out_distance = v_face >= 0 ? length(v_world - v_origin)
                               : directional_depth(v_world, v_origin, u_scene_centre,
                                                   u_scene_radius);
}
