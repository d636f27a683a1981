// How much of a surface is there (Blender's cutouts: leaves, fences, Principled Alpha): a
// cutout row (geometry.CUTOUT's texel) is (coverage layer + 1, 0 for none; 1 - the constant
// alpha; mode; 0). The layer's alpha channel gives the coverage, or with mode bit 1 its
// colour's luminance (an Image Texture's Color output, converted to a float as Cycles does);
// mode bit 2 inverts it (a Transparent BSDF in a Mix Shader's second slot). Rays and
// rasterised samples keep a surface with probability equal to its coverage (surface_kept),
// as Cycles' camera and bounce rays pick the Transparent closure by its weight.
#ifndef COVERAGE_LIB_GLSL
#define COVERAGE_LIB_GLSL
#include "common_lib.glsl"
#include "textures_lib.glsl"

float surface_coverage(usampler2DArray textures, sampler2D sizes, vec4 cutout, vec2 uv) {
    float coverage = 1.0 - cutout.y;
    if (cutout.x > 0.5) {
        vec4 s = texture_sample(textures, sizes, int(cutout.x + 0.5) - 1, uv);
        int mode = int(cutout.z + 0.5);
        float value = (mode & 1) != 0 ? dot(s.rgb, LUMINANCE) : s.a;
        if ((mode & 2) != 0) value = 1.0 - value;
        coverage *= value > 0.0 ? min(value, 1.0) : 0.0;  // NaN: 0, as the export reads it
    }
    return coverage;
}

// A cutout's coverage at uv with the g-buffer's image textures where TEXTURED binds them,
// else its constant alpha alone (uv is then not read).
#ifdef TEXTURED
#define CUTOUT_COVERAGE(cutout, uv) surface_coverage(u_textures, u_texture_sizes, cutout, uv)
#else
#define CUTOUT_COVERAGE(cutout, uv) (1.0 - (cutout).y)
#endif

// Whether a sample keyed by three words keeps a surface of this coverage.
bool surface_kept(float coverage, uvec3 key) {
    uint h = pcg(key.x + pcg(key.y + pcg(key.z)));
    return float(h >> 8) * (1.0 / 16777216.0) < coverage;
}
#endif
