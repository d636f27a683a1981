// Interleaved sampling (Keller & Heidrich 2001; Segovia et al. 2006): in each K×K block of
// pixels every pixel gathers a different 1/K² of the VPLs, those with index i where
// i % K² is the pixel's pattern index, and scales its sum by K² so the expected value is
// unchanged. A geometry-aware blur (blur_frag.glsl) then removes the K×K pattern.
// K = u_interleave must be 1 (off), 2, 4 or 8; pixels are full-image (supersampled)
// coordinates, so image tiles, which start at multiples of 1024, continue the pattern.
#ifndef INTERLEAVE_LIB_GLSL
#define INTERLEAVE_LIB_GLSL

uniform int u_interleave;  // K, the pattern's edge in pixels; unset (0) counts as 1

int interleave_size() {
    return max(u_interleave, 1);
}

// The pixel's subset of VPLs, 0 ≤ index < K², as a Bayer (ordered-dither) matrix: neighbouring
// pixels use subsets far apart in index order. The bits of (x ^ y, y), lowest first, become the
// index's bit pairs, highest first.
int interleave_pattern(ivec2 pixel) {
    int k = interleave_size();
    ivec2 cell = pixel & (k - 1);
    int index = 0;
    for (int bit = 1; bit < k; bit <<= 1) {
        index = (index << 2) | ((((cell.x ^ cell.y) & bit) != 0) ? 2 : 0)
                | (((cell.y & bit) != 0) ? 1 : 0);
    }
    return index;
}

// Whether the pixel gathers VPL vpl_index (≥ 0).
bool interleave_uses(int vpl_index, ivec2 pixel) {
    int k = interleave_size();
    return (vpl_index & (k * k - 1)) == interleave_pattern(pixel);
}

// The factor of a pixel's sum over its subset.
float interleave_weight() {
    int k = interleave_size();
    return float(k * k);
}

// The same subsets as a strided loop, whose trip count is the same for every pixel (no SIMD
// divergence, so the K²-fold saving is real):
//     for (int i = interleave_first(first, px); i < first + count; i += interleave_stride())
int interleave_stride() {
    int k = interleave_size();
    return k * k;
}

// The smallest index ≥ first (≥ 0) that the pixel uses.
int interleave_first(int first, ivec2 pixel) {
    int n = interleave_stride();
    return first + ((interleave_pattern(pixel) - first) & (n - 1));
}

#endif
