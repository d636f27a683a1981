// Stores the occluder's distance: radial from the light (cube faces) or along the axis. With
// SHADOWLESS, triangles of objects that cast no shadow (geometry.SHADOWLESS) are left out
// (lights' maps), with DIFFUSE_HIDDEN those diffuse bounces pass (geometry.DIFFUSE_HIDDEN:
// VPLs' maps), with SHADOW_LINKING those whose blocker set does not cast the tile's sample's
// shadows; with CUTOUTS, a cutout's texels are kept with probability its coverage
// (cutout_lib.glsl).
#include "common_lib.glsl"
#include "cutout_lib.glsl"

in vec3 v_world;
flat in vec3 v_origin;
flat in int v_face;

uniform vec3 u_scene_centre;
uniform float u_scene_radius;

out float out_distance;

#ifdef SHADOW_LINKING
flat in uvec2 v_blockers;

// Whether the triangle's blocker set (the triangles' row texture's third component) casts
// the tile's sample's shadows.
bool casts_tile_shadow(int triangle) {
    int width = textureSize(u_triangle_materials, 0).x;
    uint set = uint(texelFetch(u_triangle_materials, ivec2(triangle % width, triangle / width),
                               0).b);
    return (((set < 32u ? v_blockers.x : v_blockers.y) >> (set & 31u)) & 1u) != 0u;
}
#endif

void main() {
#ifdef SHADOWLESS
    if (material_of(v_triangle).texture.w > 0.5) discard;
#endif
#ifdef DIFFUSE_HIDDEN
    if (material_of(v_triangle).cutout.w > 0.5) discard;
#endif
#ifdef SHADOW_LINKING
    if (!casts_tile_shadow(v_triangle)) discard;
#endif
    if (!cutout_kept()) discard;
    out_distance = v_face >= 0 ? length(v_world - v_origin)
                               : directional_depth(v_world, v_origin, u_scene_centre,
                                                   u_scene_radius);
}
