// Imperfect shadow maps, step 3a (addon/core/ism.py): pull. Each texel of a coarser level is the
// average of the valid texels among its 2x2 finer texels of the same tile (each valid texel
// weighs the same), or empty (ISM_EMPTY) when none is valid. All tiles in one dispatch: one
// invocation per coarse texel of the whole atlas. ISM_FINE_SPLAT: the finer level is the r32ui
// splat image (empty = ISM_EMPTY_BITS), else an r32f level. ISM_TILE_LIST: listed tiles only.
#include "ism_tile_list_lib.glsl"

#define ISM_EMPTY -1.0
#define ISM_EMPTY_BITS 0xFFFFFFFFu

layout(local_size_x = 8, local_size_y = 8) in;

#ifdef ISM_FINE_SPLAT
layout(r32ui, binding = 0) uniform readonly uimage2D u_fine;

float fine_depth(ivec2 p) {
    uint bits = imageLoad(u_fine, p).r;
    return bits == ISM_EMPTY_BITS ? ISM_EMPTY : uintBitsToFloat(bits);
}
#else
layout(r32f, binding = 0) uniform readonly image2D u_fine;

float fine_depth(ivec2 p) {
    return imageLoad(u_fine, p).r;
}
#endif
layout(r32f, binding = 1) uniform writeonly image2D u_coarse;

uniform int u_fine_resolution;    // texels per tile edge of the finer level
uniform int u_coarse_resolution;  // (u_fine_resolution + 1) / 2
uniform ivec2 u_coarse_size;      // the coarse level's size: tiles * u_coarse_resolution

void main() {
    ivec2 p = ism_pass_texel(u_coarse_resolution, u_coarse_size);
    if (p.x < 0) return;
    ivec2 tile = p / u_coarse_resolution;
    ivec2 local = p - tile * u_coarse_resolution;
    float sum = 0.0;
    float count = 0.0;
    for (int j = 0; j < 2; ++j) {
        for (int i = 0; i < 2; ++i) {
            ivec2 child = 2 * local + ivec2(i, j);
            if (any(greaterThanEqual(child, ivec2(u_fine_resolution)))) continue;
            float depth = fine_depth(tile * u_fine_resolution + child);
            if (depth >= 0.0) {
                sum += depth;
                count += 1.0;
            }
        }
    }
    imageStore(u_coarse, p, vec4(count > 0.0 ? sum / count : ISM_EMPTY));
}
