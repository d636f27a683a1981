// For the fragment shaders of draws from shadow_vert.glsl (shadow maps, RSMs): the triangle
// index (with SHADOWLESS, DIFFUSE_HIDDEN, CUTOUTS, TRIANGLES or SHADOW_LINKING) and
// cutout_kept(), whether
// this fragment keeps its surface: with CUTOUTS (some material is a cutout) with probability
// its coverage (coverage_lib.glsl; TEXTURED: its image textures are bound), else always.
#ifndef CUTOUT_LIB_GLSL
#define CUTOUT_LIB_GLSL
#if defined(SHADOWLESS) || defined(DIFFUSE_HIDDEN) || defined(CUTOUTS) || defined(TRIANGLES) \
    || defined(SHADOW_LINKING)
#include "materials_lib.glsl"
flat in int v_triangle;
#endif
#ifdef CUTOUTS
#include "coverage_lib.glsl"
#ifdef TEXTURED
in vec2 v_uv;
#endif
#endif

bool cutout_kept() {
#ifdef CUTOUTS
    return surface_kept(CUTOUT_COVERAGE(material_of(v_triangle).cutout, v_uv),
                        uvec3(gl_FragCoord.xy, v_triangle));
#else
    return true;
#endif
}
#endif
