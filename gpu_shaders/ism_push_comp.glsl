// Imperfect shadow maps, step 3b (addon/core/ism.py): push, from the coarsest level to the
// finest. A valid texel keeps its depth bit for bit; an empty one gets the bilinear
// interpolation of the (already pushed) coarser level of its tile, over the valid coarse taps
// only (weights renormalised), or u_unfilled where none is valid (ISM_EMPTY on coarse levels,
// ISM_FAR on the finest: lit). On the finest level a splat that the coarser level shows over
// ISM_BEHIND times nearer on both sides counts as a hole too (hole_in_nearer): it is a farther
// surface seen through a gap between a nearer surface's splats, which would let light through a
// closed wall. All tiles in one dispatch: one invocation per texel.
// ISM_FINE_SPLAT: the finest level, read from the r32ui splat image (which is reset to empty for
// the next frame as it is read) and written to the r32f atlas; else an r32f level in place.
// ISM_TILE_LIST: only the listed tiles (a partial update); the others keep the depths of an
// earlier frame.
#include "ism_tile_list_lib.glsl"

#define ISM_EMPTY -1.0
#define ISM_EMPTY_BITS 0xFFFFFFFFu
#define ISM_BEHIND 1.25

layout(local_size_x = 8, local_size_y = 8) in;

#ifdef ISM_FINE_SPLAT
layout(r32ui, binding = 0) uniform uimage2D u_splat;
layout(r32f, binding = 2) uniform writeonly image2D u_atlas;

float take_depth(ivec2 p) {
    uint bits = imageLoad(u_splat, p).r;
    imageStore(u_splat, p, uvec4(ISM_EMPTY_BITS));
    return bits == ISM_EMPTY_BITS ? ISM_EMPTY : uintBitsToFloat(bits);
}

void put_depth(ivec2 p, float depth) {
    imageStore(u_atlas, p, vec4(depth));
}
#else
layout(r32f, binding = 0) uniform image2D u_level;

float take_depth(ivec2 p) {
    return imageLoad(u_level, p).r;
}

void put_depth(ivec2 p, float depth) {
    imageStore(u_level, p, vec4(depth));
}
#endif
layout(r32f, binding = 1) uniform readonly image2D u_coarse;

uniform int u_resolution;         // texels per tile edge of this level
uniform int u_coarse_resolution;  // of the coarser level; 0: none (no pull-push)
uniform ivec2 u_size;             // this level's size: tiles * u_resolution
uniform float u_unfilled;

// Bilinear interpolation of the coarse level of `tile` at continuous coarse texel coordinates
// `c`, over its valid texels only; u_unfilled where none of the four is valid.
float coarse_depth(ivec2 tile, vec2 c) {
    ivec2 base = ivec2(floor(c));
    vec2 f = c - vec2(base);
    float sum = 0.0;
    float weight = 0.0;
    for (int j = 0; j < 2; ++j) {
        for (int i = 0; i < 2; ++i) {
            ivec2 q = clamp(base + ivec2(i, j), ivec2(0), ivec2(u_coarse_resolution - 1));
            float depth = imageLoad(u_coarse, tile * u_coarse_resolution + q).r;
            float w = (i == 0 ? 1.0 - f.x : f.x) * (j == 0 ? 1.0 - f.y : f.y);
            if (depth >= 0.0 && w > 0.0) {
                sum += w * depth;
                weight += w;
            }
        }
    }
    return weight > 0.0 ? sum / weight : u_unfilled;
}

// Whether a splat at `depth` in texel `local` of `tile` is a farther surface seen through a gap
// of a nearer one: the coarser level one coarse texel away on both sides, left and right or
// below and above, is over ISM_BEHIND times nearer. Beside the edge of a nearer surface only
// one side is: silhouettes stay where they are.
bool hole_in_nearer(ivec2 tile, vec2 local, float depth) {
    vec2 c = (local + 0.5) * 0.5 - 0.5;
    float limit = depth / ISM_BEHIND;
    float l = coarse_depth(tile, c - vec2(1.0, 0.0));
    float r = coarse_depth(tile, c + vec2(1.0, 0.0));
    float b = coarse_depth(tile, c - vec2(0.0, 1.0));
    float t = coarse_depth(tile, c + vec2(0.0, 1.0));
    return (l >= 0.0 && l < limit && r >= 0.0 && r < limit)
        || (b >= 0.0 && b < limit && t >= 0.0 && t < limit);
}

void main() {
    ivec2 p = ism_pass_texel(u_resolution, u_size);
    if (p.x < 0) return;
    float depth = take_depth(p);
    ivec2 tile = p / u_resolution;
    vec2 local = vec2(p - tile * u_resolution);
    float filled = u_unfilled;
    if (u_coarse_resolution > 0) filled = coarse_depth(tile, (local + 0.5) * 0.5 - 0.5);
#ifdef ISM_FINE_SPLAT
    if (depth >= 0.0 && u_coarse_resolution > 0 && hole_in_nearer(tile, local, depth))
        depth = ISM_EMPTY;  // filled like any hole
#endif
    put_depth(p, depth >= 0.0 ? depth : filled);
}
