// Interleaved sampling (Keller & Heidrich 2001; Segovia et al. 2006): in each K×K block of
// pixels every pixel gathers a different 1/K² of the VPLs, those with index i where
// i % K² is the pixel's pattern index, and scales its sum by K² so the expected value is
// unchanged. A geometry-aware blur (blur_frag.glsl) then removes the K×K pattern.
// K = u_interleave is 1 (off), a power of two (a Bayer matrix: 2, 4 or 8) or another size
// (K = 3, the antialiasing factor, gives each pixel's 3×3 supersamples every subset once: see
// interleave_pattern). Pixels are tile coordinates; tiles start at multiples of 1024 and of
// the antialiasing factor, so the pattern continues across them where K divides those.
#ifndef INTERLEAVE_LIB_GLSL
#define INTERLEAVE_LIB_GLSL

uniform int u_interleave;  // K, the pattern's edge in pixels; unset (0) counts as 1

int interleave_size() {
    return max(u_interleave, 1);
}

// Whether the pattern is a Bayer matrix (K a power of two) rather than the centred order of
// other sizes (interleave_pattern).
bool interleave_is_bayer() {
    int k = interleave_size();
    return (k & (k - 1)) == 0;
}

// The pixel's subset of VPLs, 0 ≤ index < K², as a Bayer (ordered-dither) matrix: neighbouring
// pixels use subsets far apart in index order. The bits of (x ^ y, y), lowest first, become the
// index's bit pairs, highest first.
//
// Other sizes (the antialiasing factor 3, 5, 6 or 7): the block's cells ordered from the centre
// out in pairs mirrored through it, so that the first r subsets, which hold one sample more
// when a draw's count is not a multiple of K², lie symmetrically about the block's centre
// (its samples' weighted position stays the centre); their indices count from the draw's
// first sample (interleave_first).
int interleave_pattern(ivec2 pixel) {
    int k = interleave_size();
    if (!interleave_is_bayer()) {
        ivec2 cell = pixel % k;
        int n = k * k, middle = n / 2, odd = n % 2;
        int p = cell.x + k * cell.y;  // its mirror is n - 1 - p
        if (odd == 1 && p == middle) return 0;
        return p < middle ? odd + 2 * p : odd + 2 * (n - 1 - p) + 1;
    }
    ivec2 cell = pixel & (k - 1);
    int index = 0;
    for (int bit = 1; bit < k; bit <<= 1) {
        index = (index << 2) | ((((cell.x ^ cell.y) & bit) != 0) ? 2 : 0)
                | (((cell.y & bit) != 0) ? 1 : 0);
    }
    return index;
}

// Whether the pixel gathers index vpl_index (≥ 0) of a draw starting at index 0.
bool interleave_uses(int vpl_index, ivec2 pixel) {
    int k = interleave_size();
    return vpl_index % (k * k) == interleave_pattern(pixel);
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

// The smallest index ≥ first (≥ 0) that the pixel uses: for a power of two of all the
// indices, for other sizes of the draw's own, counted from first.
int interleave_first(int first, ivec2 pixel) {
    if (!interleave_is_bayer()) return first + interleave_pattern(pixel);
    int n = interleave_stride();
    return first + ((interleave_pattern(pixel) - first) & (n - 1));
}

#endif
