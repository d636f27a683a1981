// Shadow-map rendering: every atlas tile (a cube face or a directional map) in one instanced
// draw (see tiles_lib.glsl). With CLEAR, the clear triangles for an atlas's clear layer
// (shadow_clear_frag.glsl), with their normals and the light they let through; with
// SHADOW_LINKING the tile's blocker sets; with SHADOWLESS, DIFFUSE_HIDDEN, CUTOUTS,
// TRIANGLES or SHADOW_LINKING, the triangle index for the fragment
// shader (and with CUTOUTS and TEXTURED its UVs; cutout_lib.glsl). Also the vertex shader of
// rsm_frag.glsl.
#include "tiles_lib.glsl"

in vec3 in_position;

out vec3 v_world;
flat out vec3 v_origin;
flat out int v_face;

#if defined(SHADOWLESS) || defined(DIFFUSE_HIDDEN) || defined(CUTOUTS) || defined(TRIANGLES) \
    || defined(SHADOW_LINKING)
#define TRIANGLE_INDEX
flat out int v_triangle;
#endif
#ifdef SHADOW_LINKING
uniform usampler2D u_tile_blockers;  // per tile: its sample's blocker sets (a table)
flat out uvec2 v_blockers;
#endif
#if defined(CUTOUTS) && defined(TEXTURED)
in vec2 in_uv;
out vec2 v_uv;
#endif
#ifdef CLEAR
in vec3 in_normal;          // the triangle's unit normal
in vec4 in_transmission;    // colour let through, Fresnel IOR (0: no Fresnel loss)
flat out vec3 v_normal;
flat out vec4 v_transmission;
#endif

void main() {
    gl_Position = atlas_tile_position(in_position, gl_InstanceID, v_origin, v_face);
    v_world = in_position;
#ifdef TRIANGLE_INDEX
    v_triangle = gl_VertexID / 3;  // instanced draws do not reset it
#endif
#ifdef SHADOW_LINKING
    int width = textureSize(u_tile_blockers, 0).x;
    v_blockers = texelFetch(u_tile_blockers, ivec2(gl_InstanceID % width, gl_InstanceID / width),
                            0).xy;
#endif
#if defined(CUTOUTS) && defined(TEXTURED)
    v_uv = in_uv;
#endif
#ifdef CLEAR
    v_normal = in_normal;
    v_transmission = in_transmission;
#endif
}
