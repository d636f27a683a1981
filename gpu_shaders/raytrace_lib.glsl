// Ray tracing against the scene BVH uploaded by addon/core/raytrace.py (RayTracer.bind() binds
// it). Needs `#version 430`. Triangles are two-sided; a hit counts when t_min < t < t_max, t
// being the ray parameter along `dir` (the distance when `dir` is a unit vector; any non-zero
// length works). A zero `dir` misses everything. Names starting with rt_ / Rt / RT_ are taken.
// Pass `dir` at run time (a uniform, a buffer, a computed value): NVIDIA's driver 580 missed
// every ray when it was a compile-time constant (raytrace_test_comp.glsl). With RT_CUTOUTS
// (set by RayTracer.upload for scenes with cutouts) cutout triangles are hit with probability
// their coverage (coverage_lib.glsl), and shadow rays are dimmed by what they let through.
#ifndef RAYTRACE_LIB_GLSL
#define RAYTRACE_LIB_GLSL
#include "fresnel_lib.glsl"

#define RT_BINDING_NODES 10
#define RT_BINDING_TRIANGLES 11
#define RT_BINDING_CUTOUTS 14
#define RT_UNIT_TEXTURES 16  // texture units of the cutouts' image textures and their sizes
#define RT_UNIT_TEXTURE_SIZES 17
#define RT_STACK_SIZE 64  // >= the BVH depth (checked when it is built)

// Relative growth of a box's exit distance, covering the rounding of the slab test (2 gamma(3)
// of Ize 2013, "Robust BVH Ray Traversal") so boxes that just contain a hit are never missed.
#define RT_BOX_GROWTH 4.0e-7
// Direction components smaller than this fraction of the largest one are replaced by it (with
// their sign) in the slab test, so 1/d stays finite and no 0 * inf NaN can arise.
#define RT_MIN_DIR_FRACTION 1.0e-20

// Interior node: a = left child, a + 1 = right child, b = -1. Leaf: triangles a .. a + b - 1.
struct RtNode {
    vec3 lo;
    int a;
    vec3 hi;
    int b;
};

// Vertices in leaf order and `id`, the triangle's index in the caller's original list. A clear
// triangle (clear: packUnorm4x8 of the colour it lets through, alpha 1) is never hit;
// rt_transmittance dims rays crossing it by its colour and, with ior > 0, the Fresnel loss.
// Otherwise `clear` holds flags: a shadowless triangle (RT_SHADOWLESS: an object whose Shadow
// ray visibility is off) is opaque to every ray but shadow rays (RT_SHADOW), a diffuse-hidden
// one (RT_DIFFUSE_HIDDEN: Diffuse ray visibility off) to every ray but diffuse bounces
// (RT_DIFFUSE); a cutout (RT_CUTOUT) has its row of rt_cutouts in `ior`'s bits; bits
// RT_BLOCKER_SHIFT on hold its shadow-linking blocker set (RT_SHADOW_LINKING).
struct RtTriangle {
    vec3 v0;
    int id;
    vec3 v1;
    uint clear;
    vec3 v2;
    float ior;
};

layout(std430, binding = RT_BINDING_NODES) readonly buffer RtNodes { RtNode rt_nodes[]; };
layout(std430, binding = RT_BINDING_TRIANGLES) readonly buffer RtTriangles {
    RtTriangle rt_triangles[];
};

#ifdef RT_CUTOUTS
#include "coverage_lib.glsl"
// A cutout triangle's UVs and its cutout texel (coverage_lib.glsl), its layer one of
// rt_textures'.
struct RtCutout {
    vec2 uv0;
    vec2 uv1;
    vec2 uv2;
    vec2 unused;
    vec4 cutout;
};
layout(std430, binding = RT_BINDING_CUTOUTS) readonly buffer RtCutouts { RtCutout rt_cutouts[]; };
layout(binding = RT_UNIT_TEXTURES) uniform usampler2DArray rt_textures;
layout(binding = RT_UNIT_TEXTURE_SIZES) uniform sampler2D rt_texture_sizes;

float rt_coverage(RtTriangle tri, vec2 barycentric) {
    RtCutout c = rt_cutouts[floatBitsToInt(tri.ior)];
    vec2 uv = c.uv0 + barycentric.x * (c.uv1 - c.uv0) + barycentric.y * (c.uv2 - c.uv0);
    return surface_coverage(rt_textures, rt_texture_sizes, c.cutout, uv);
}

// The key of a ray's choice at a cutout: the same ray makes the same choice.
uvec3 rt_cutout_key(vec3 origin, vec3 dir, int triangle) {
    uvec3 o = floatBitsToUint(origin), d = floatBitsToUint(dir);
    return uvec3(o.x ^ d.y, o.y ^ d.z, o.z ^ d.x ^ uint(triangle));
}
#endif

// Per-ray constants: the slab test's inverse direction, and the shear taking the ray to +z
// for the watertight triangle test (Woop, Benthin, Wald 2013).
struct RtRay {
    vec3 origin;
    vec3 inv_dir;
    mat3 shear;
};

RtRay rt_make_ray(vec3 origin, vec3 dir) {
    vec3 a = abs(dir);
    int kz = a.x >= a.y && a.x >= a.z ? 0 : (a.y >= a.z ? 1 : 2);
    int kx = kz == 2 ? 0 : kz + 1;
    int ky = kx == 2 ? 0 : kx + 1;
    if (dir[kz] < 0.0) {  // keep the winding, as in the paper (either works two-sided)
        int k = kx;
        kx = ky;
        ky = k;
    }
    // Rows: ray-space x = p[kx] - Sx p[kz], y = p[ky] - Sy p[kz], z = p[kz] / dir[kz].
    mat3 shear = mat3(0.0);
    shear[kx][0] = 1.0;
    shear[ky][1] = 1.0;
    shear[kz] = vec3(-dir[kx] / dir[kz], -dir[ky] / dir[kz], 1.0 / dir[kz]);

    float tiny = a[kz] * RT_MIN_DIR_FRACTION;
    vec3 safe = mix(dir, mix(vec3(-tiny), vec3(tiny), greaterThanEqual(dir, vec3(0.0))),
                    lessThan(a, vec3(tiny)));
    return RtRay(origin, 1.0 / safe, shear);
}

// Exit distance grown by RT_BOX_GROWTH whatever its sign; never NaN, also for +-inf.
float rt_grow(float t) {
    return max(t * (1.0 + RT_BOX_GROWTH), t * (1.0 - RT_BOX_GROWTH));
}

bool rt_hit_box(RtRay ray, vec3 lo, vec3 hi, float t_min, float t_max, out float t_near) {
    vec3 t0 = (lo - ray.origin) * ray.inv_dir;
    vec3 t1 = (hi - ray.origin) * ray.inv_dir;
    vec3 near = min(t0, t1);
    vec3 far = max(t0, t1);
    t_near = max(max(near.x, near.y), max(near.z, t_min));
    float t_far = min(min(far.x, far.y), min(far.z, t_max));
    return t_near <= rt_grow(t_far);
}

// Watertight two-sided test; degenerate triangles (det == 0) never hit.
bool rt_hit_triangle(RtRay ray, RtTriangle tri, float t_min, float t_max, out float t,
                     out vec2 uv) {
    precise vec3 a = ray.shear * (tri.v0 - ray.origin);
    precise vec3 b = ray.shear * (tri.v1 - ray.origin);
    precise vec3 c = ray.shear * (tri.v2 - ray.origin);
    precise float u = c.x * b.y - c.y * b.x;
    precise float v = a.x * c.y - a.y * c.x;
    precise float w = b.x * a.y - b.y * a.x;
    if ((u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0)) return false;
    float det = u + v + w;
    if (det == 0.0) return false;
    t = (u * a.z + v * b.z + w * c.z) / det;
    uv = vec2(v, w) / det;
    return t > t_min && t < t_max;
}

// The light a clear triangle lets through along `dir` (fresnel_lib.glsl's clear_crossing).
vec3 rt_clear_transmittance(RtTriangle tri, vec3 dir) {
    vec3 colour = unpackUnorm4x8(tri.clear).rgb;
    if (tri.ior <= 0.0) return colour;
    vec3 n = cross(tri.v1 - tri.v0, tri.v2 - tri.v0);
    float cos_i = abs(dot(n, dir)) / max(length(n) * length(dir), 1.0e-30);
    return clear_crossing(colour, tri.ior, cos_i);
}

#define RT_CLOSEST 0
#define RT_ANY 1
#define RT_TRANSMIT 2
#define RT_SHADOW 4  // or'ed into a mode: a shadow ray, which shadowless triangles let through
#define RT_PASSED 8  // or'ed into RT_TRANSMIT: cutouts were passed by chance, they do not dim
#define RT_DIFFUSE 16  // or'ed into a mode: a diffuse bounce, which diffuse-hidden triangles pass
#define RT_SHADOWLESS 1u  // RtTriangle.clear flag of a shadowless triangle
#define RT_CUTOUT 2u  // RtTriangle.clear flag of a cutout triangle
#define RT_DIFFUSE_HIDDEN 4u  // RtTriangle.clear flag of a diffuse-hidden triangle
#define RT_BLOCKER_SHIFT 8u  // RtTriangle.clear's flags: the blocker set from this bit on
#define RT_FLAGS 65535u  // RtTriangle.clear values up to this hold flags, not a colour

#ifdef RT_SHADOW_LINKING
// Shadow linking: the blocker sets (Instance.blocker_set: bits 0-31, 32-63) whose triangles
// the rays traced now stop, those that cast the shadows of the emitter they come from
// (LightSamples.blockers); set it before tracing, all bits for the rays of no emitter.
uvec2 rt_blockers = uvec2(0xFFFFFFFFu);

bool rt_blocks(uint code) {
    uint set = code <= RT_FLAGS ? (code >> RT_BLOCKER_SHIFT) & 63u : 0u;
    return (((set < 32u ? rt_blockers.x : rt_blockers.y) >> (set & 31u)) & 1u) != 0u;
}
#endif

// Nearest-child-first stack traversal of the opaque triangles. RT_ANY returns at the first hit
// in range; RT_TRANSMIT multiplies `transmittance` by every clear triangle in range and by
// one minus every cutout's coverage (none with RT_PASSED), and sets it to 0 at the first opaque
// hit; with RT_SHADOW or'ed in, shadowless triangles are not hit, with RT_DIFFUSE
// diffuse-hidden ones. RT_CLOSEST and RT_ANY hit a cutout with probability its coverage.
bool rt_trace(vec3 origin, vec3 dir, float t_min, float t_max, int flags, out float t,
              out int triangle, out vec2 uv, inout vec3 transmittance) {
    int mode = flags & 3;
    uint passed = ((flags & RT_SHADOW) != 0 ? RT_SHADOWLESS : 0u)
                  | ((flags & RT_DIFFUSE) != 0 ? RT_DIFFUSE_HIDDEN : 0u);
    t = t_max;
    triangle = -1;
    uv = vec2(0.0);
    if (!(t_min < t_max) || dir == vec3(0.0)) return false;
    RtRay ray = rt_make_ray(origin, dir);
    float t_root;
    if (!rt_hit_box(ray, rt_nodes[0].lo, rt_nodes[0].hi, t_min, t, t_root)) return false;

    int stack[RT_STACK_SIZE];
    float stack_near[RT_STACK_SIZE];
    int size = 0;
    int node = 0;
    while (true) {
        RtNode n = rt_nodes[node];
        if (n.b < 0) {
            float t_left, t_right;
            bool left = rt_hit_box(ray, rt_nodes[n.a].lo, rt_nodes[n.a].hi, t_min, t, t_left);
            bool right = rt_hit_box(ray, rt_nodes[n.a + 1].lo, rt_nodes[n.a + 1].hi, t_min, t,
                                    t_right);
            if (left && right) {
                bool left_first = t_left <= t_right;
                stack[size] = left_first ? n.a + 1 : n.a;
                stack_near[size] = left_first ? t_right : t_left;
                ++size;
                node = left_first ? n.a : n.a + 1;
                continue;
            }
            if (left || right) {
                node = left ? n.a : n.a + 1;
                continue;
            }
        } else {
            for (int i = n.a; i < n.a + n.b; ++i) {
                float t_hit;
                vec2 uv_hit;
                if (rt_hit_triangle(ray, rt_triangles[i], t_min, t, t_hit, uv_hit)) {
                    uint code = rt_triangles[i].clear;
#ifdef RT_SHADOW_LINKING
                    if (!rt_blocks(code)) continue;
#endif
                    if (code != 0u) {  // rare: checked on hits only
                        if (code <= RT_FLAGS) {
                            if ((code & passed) != 0u) continue;
#ifdef RT_CUTOUTS
                            if ((code & RT_CUTOUT) != 0u) {
                                if (mode == RT_TRANSMIT && (flags & RT_PASSED) != 0) continue;
                                float coverage = rt_coverage(rt_triangles[i], uv_hit);
                                if (mode == RT_TRANSMIT) {
                                    transmittance *= 1.0 - coverage;
                                    if (transmittance == vec3(0.0)) return true;
                                    continue;
                                }
                                if (!surface_kept(coverage, rt_cutout_key(origin, dir, i))) {
                                    continue;
                                }
                            }
#endif
                        } else {
                            if (mode == RT_TRANSMIT) {
                                transmittance *= rt_clear_transmittance(rt_triangles[i], dir);
                                if (transmittance == vec3(0.0)) return true;
                            }
                            continue;
                        }
                    }
                    if (mode == RT_TRANSMIT) {
                        transmittance = vec3(0.0);
                        return true;
                    }
                    t = t_hit;
                    uv = uv_hit;
                    triangle = rt_triangles[i].id;
                    if (mode == RT_ANY) return true;
                }
            }
        }
        // Pop the nearest pending node that may still hold a closer hit.
        do {
            if (size == 0) return triangle >= 0;
            --size;
        } while (stack_near[size] > rt_grow(t));
        node = stack[size];
    }
}

// Closest hit with t_min < t < t_max: its t, ORIGINAL triangle index and barycentric (u, v) =
// weights of vertices 1 and 2. On a miss, returns false with triangle = -1.
bool rt_closest_hit(vec3 origin, vec3 dir, float t_min, float t_max, out float t,
                    out int triangle, out vec2 uv) {
    vec3 unused = vec3(1.0);
    return rt_trace(origin, dir, t_min, t_max, RT_CLOSEST, t, triangle, uv, unused);
}

// rt_closest_hit of a diffuse bounce (RT_DIFFUSE: diffuse-hidden triangles are passed).
bool rt_diffuse_hit(vec3 origin, vec3 dir, float t_min, float t_max, out float t,
                    out int triangle, out vec2 uv) {
    vec3 unused = vec3(1.0);
    return rt_trace(origin, dir, t_min, t_max, RT_CLOSEST | RT_DIFFUSE, t, triangle, uv, unused);
}

// Whether anything opaque is hit with t_min < t < t_max (any hit, early exit).
bool rt_occluded(vec3 origin, vec3 dir, float t_min, float t_max) {
    float t;
    int triangle;
    vec2 uv;
    vec3 unused = vec3(1.0);
    return rt_trace(origin, dir, t_min, t_max, RT_ANY, t, triangle, uv, unused);
}

// The light let through from t_min to t_max: 0 where anything opaque is in the way, else the
// product of the clear triangles' transmittance and the cutouts'; `flags`: 0 or RT_SHADOW or
// RT_DIFFUSE, and RT_PASSED.
vec3 rt_transmittance(vec3 origin, vec3 dir, float t_min, float t_max, int flags) {
    float t;
    int triangle;
    vec2 uv;
    vec3 transmittance = vec3(1.0);
    rt_trace(origin, dir, t_min, t_max, RT_TRANSMIT | flags, t, triangle, uv, transmittance);
    return transmittance;
}
#endif
