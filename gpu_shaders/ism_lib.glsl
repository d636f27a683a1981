// Imperfect shadow maps (Ritschel et al. 2008, addon/core/ism.py): the paraboloid projection
// shared by the point splat (ism_splat_comp.glsl) and the lookup, and the lookup itself.
//
// A VPL is a one-sided cosine emitter, so its map covers the hemisphere around its normal: in the
// VPL's frame (z = normal) a unit direction d with d.z > 0 maps to uv = d.xy / (1 + d.z) in the
// unit disk, and uv in [-1, 1]^2 spans one tile of `resolution`^2 texels of the atlas (tile k at
// column k % columns, row k / columns). A texel holds the distance from the VPL to the nearest
// point seen through it; texels that no point reached, even after pull-push, hold ISM_FAR (lit).
#ifndef ISM_LIB_GLSL
#define ISM_LIB_GLSL
#include "common_lib.glsl"

#define ISM_FAR 3.0e38
// The receiver's offset along its normal, in multiples of the bias (the depth tolerance). A
// lifted receiver seen at a grazing angle clears its own surface's nearer texels (which the
// 2×2 filter reads) by offset / cosine, while light through a joint between walls still meets
// the same depth tolerance. Measured at 1 / 1.5 / 2 / 3: the interior 9.5 / 9.3 / 9.2 / 9.3 %
// error (energy -2.1 / -1.9 / -1.6 / -1.3 %), the Cornell box 5.32 / 5.31 / 5.32 / 5.35 %, the
// closed cube's leak 9.6 / 10.3 / 10.3 / 9.8 % (bound 12 %); at 1 / 1.5 / 2, shadowed floor
// points found lit under an analytic occluder 1.6 / 3.2 / 5.2 % (tests/core/test_ism.py).
#define ISM_NORMAL_OFFSET 1.5

// Map `world` into the paraboloid map of a VPL at `origin` with unit `normal`: `map` = (uv,
// cosine to the normal), `distance` = |world - origin|. False behind the VPL or at it.
bool ism_project(vec3 origin, vec3 normal, vec3 world, out vec3 map, out float distance) {
    vec3 t, b;
    basis_of(normal, t, b);
    vec3 v = world - origin;
    distance = length(v);
    vec3 d = vec3(dot(v, t), dot(v, b), dot(v, normal)) / distance;
    map = vec3(d.xy / (1.0 + d.z), d.z);
    return distance > 0.0 && d.z > 0.0;
}

// The unit direction, in the VPL's frame, that maps to `uv` (the inverse of ism_project).
vec3 ism_local_direction(vec2 uv) {
    float r2 = dot(uv, uv);
    return vec3(2.0 * uv, 1.0 - r2) / (1.0 + r2);
}

// Continuous texel coordinates (0 .. resolution) of a map position inside its tile.
vec2 ism_texel(vec3 map, float resolution) {
    return (map.xy * 0.5 + 0.5) * resolution;
}

// World size of one texel at `distance` along a direction of cosine `cos_normal`: the map's
// angular texel size is (2 / resolution) (1 + cos), from 2 / res at the centre to 4 / res at
// the rim.
float ism_texel_size(float distance, float cos_normal, float resolution) {
    return distance * 2.0 * (1.0 + cos_normal) / resolution;
}

// 1 where `receiver` is not behind the depth of `texel` (clamped into the tile), else 0.
float ism_tap(sampler2D atlas, ivec2 origin, int size, ivec2 texel, float receiver) {
    float occluder = texelFetch(atlas, origin + clamp(texel, ivec2(0), ivec2(size - 1)), 0).r;
    return receiver <= occluder ? 1.0 : 0.0;
}

// Percentage-closer filtering of the 2x2 texels around map position `map` of a tile, weighted
// bilinearly (exactly 1 when all four are lit).
float ism_filtered(sampler2D atlas, int tile, int columns, float resolution, vec3 map,
                   float receiver) {
    int size = int(resolution);
    ivec2 origin = ivec2(tile % columns, tile / columns) * size;
    vec2 q = ism_texel(map, resolution) - 0.5;
    ivec2 base = ivec2(floor(q));
    vec2 f = q - vec2(base);
    float a = ism_tap(atlas, origin, size, base, receiver);
    float b = ism_tap(atlas, origin, size, base + ivec2(1, 0), receiver);
    float c = ism_tap(atlas, origin, size, base + ivec2(0, 1), receiver);
    float d = ism_tap(atlas, origin, size, base + ivec2(1, 1), receiver);
    float bottom = a + (b - a) * f.x;
    float top = c + (d - c) * f.x;
    return bottom + (top - bottom) * f.y;
}

// Fraction of a VPL's light reaching `world`. The receiver is moved ISM_NORMAL_OFFSET × `bias`
// texels along its geometric normal (turned towards the VPL), and may lie up to `bias` texels
// behind the stored depth: both are relative to the texel size, so the test does not depend on
// the scene's scale. Points behind the VPL get 1: its cosine is zero there.
float ism_visibility(sampler2D atlas, int tile, int columns, float resolution,
                     vec3 vpl_position, vec3 vpl_normal, vec3 world, vec3 geometric_normal,
                     float bias) {
    vec3 map;
    float distance;
    if (!ism_project(vpl_position, vpl_normal, world, map, distance)) return 1.0;
    float texel_size = ism_texel_size(distance, map.z, resolution);
    vec3 n = faceforward(geometric_normal, world - vpl_position, geometric_normal);
    vec3 p = world + n * (ISM_NORMAL_OFFSET * bias * texel_size);
    if (!ism_project(vpl_position, vpl_normal, p, map, distance)) return 1.0;
    return ism_filtered(atlas, tile, columns, resolution, map, distance - bias * texel_size);
}

// Directional imperfect shadow maps (sun and world samples): an orthographic map along the
// direction of travel `axis` over the scene's bounding sphere; depth is measured along the axis
// from the sphere's front.
void ism_project_directional(vec3 axis, vec3 centre, float radius, vec3 world, out vec3 map,
                             out float depth) {
    vec3 t, b;
    basis_of(axis, t, b);
    vec3 v = world - centre;
    map = vec3(dot(v, t) / radius, dot(v, b) / radius, 1.0);
    depth = dot(v, axis) + radius;
}

float ism_visibility_directional(sampler2D atlas, int tile, int columns, float resolution,
                                 vec3 axis, vec3 centre, float radius, vec3 world,
                                 vec3 geometric_normal, float bias) {
    float texel_size = 2.0 * radius / resolution;
    vec3 n = faceforward(geometric_normal, axis, geometric_normal);
    vec3 map;
    float depth;
    ism_project_directional(axis, centre, radius, world + n * (ISM_NORMAL_OFFSET * bias
                                                                 * texel_size), map, depth);
    return ism_filtered(atlas, tile, columns, resolution, map, depth - bias * texel_size);
}
#endif
