// Imperfect shadow maps, step 1 (addon/core/gpu/ism.py): surface points drawn on the GPU, so
// nothing of size points x VPLs is sampled on the CPU or uploaded. Point i of set s (the atlas
// tile) is stratum i of a systematic sample of the triangles' area CDF with an offset hashed
// from (seed, s): each triangle gets the floor or the ceiling of its expected share of the set.
// The j-th point of a set on one triangle takes the j-th point of Roberts' R2 sequence, shifted
// by a hash of (seed, s, triangle) and folded from the unit square into the triangle, so a
// set's points on a large triangle are spread evenly. Integer hashes throughout: the same seed
// gives the same points on every run.
#ifndef ISM_POINTS_LIB_GLSL
#define ISM_POINTS_LIB_GLSL

#include "common_lib.glsl"

#define ISM_BINDING_CDF 20
#define ISM_BINDING_GUIDE 27

// Cumulative triangle area / total area (float), the last exactly 1; zero-area triangles
// repeat the previous value and are never drawn.
layout(std430, binding = ISM_BINDING_CDF) readonly buffer IsmCdf { float ism_cdf[]; };
// u_triangle_count + 1 entries: entry g is the first triangle whose CDF exceeds g / count.
layout(std430, binding = ISM_BINDING_GUIDE) readonly buffer IsmGuide { uint ism_guide[]; };

uniform int u_points_per_vpl;
uniform int u_triangle_count;
uniform uint u_point_seed;

const uvec2 ISM_R2 = uvec2(3242174889u, 2447445414u);  // Roberts' R2 step, 0.32 fixed point
const float ISM_BELOW_ONE = 0.99999994;  // the largest float below 1

// A uniform number in [0, 1) from 32 random bits (their top 24: exact in a float).
float ism_unit(uint bits) {
    return float(bits >> 8u) * (1.0 / 16777216.0);
}

// Where stratum j of a set with offset `offset` falls on the CDF.
float ism_stratum(int j, float offset) {
    return min((float(j) + offset) / float(u_points_per_vpl), ISM_BELOW_ONE);
}

// Point i of set `set`: its triangle and the barycentric weights of its vertices 1 and 2.
void ism_surface_point(int set, int i, out int triangle, out vec2 bary) {
    uint key = pcg(u_point_seed ^ pcg(uint(set)));
    float offset = ism_unit(key);
    float x = ism_stratum(i, offset);
    // The first triangle whose CDF exceeds x, between the guide entries around x: one cell
    // more on each side, since the float product may miss the cell by one.
    int cell = min(int(x * float(u_triangle_count)), u_triangle_count - 1);
    int lo = int(ism_guide[max(cell - 1, 0)]);
    int hi = min(int(ism_guide[min(cell + 2, u_triangle_count)]), u_triangle_count - 1);
    while (lo < hi) {
        int mid = (lo + hi) >> 1;
        if (ism_cdf[mid] > x) hi = mid; else lo = mid + 1;
    }
    triangle = lo;
    // The triangle's first stratum: the least j whose stratum reaches the CDF below it.
    float below = lo > 0 ? ism_cdf[lo - 1] : 0.0;
    int first = clamp(int(ceil(below * float(u_points_per_vpl) - offset)), 0, i);
    while (first > 0 && ism_stratum(first - 1, offset) >= below) --first;
    while (first < i && ism_stratum(first, offset) < below) ++first;
    uint shift = pcg(key ^ pcg(uint(triangle) + 2654435769u));
    uvec2 uv_bits = uvec2(shift, pcg(shift)) + uint(i - first) * ISM_R2;
    bary = vec2(ism_unit(uv_bits.x), ism_unit(uv_bits.y));
    if (bary.x + bary.y > 1.0) bary = 1.0 - bary;
}

#endif
