// Batch ray queries for RayTracer.intersect / occluded (addon/core/raytrace.py): one ray per
// invocation, rays and results in storage buffers. RT_ANY_HIT (0 or 1) picks the query.
#include "raytrace_lib.glsl"

#define RT_BINDING_RAYS 12
#define RT_BINDING_RESULTS 13

layout(local_size_x = 64) in;

struct RtQuery {
    vec3 origin;
    float t_min;
    vec3 dir;  // unit length: t is a distance
    float t_max;
};

layout(std430, binding = RT_BINDING_RAYS) readonly buffer RtQueries { RtQuery rt_queries[]; };

#if RT_ANY_HIT
layout(std430, binding = RT_BINDING_RESULTS) writeonly buffer RtOccluded { int rt_occluded_out[]; };
#else
struct RtHit {
    float t;
    int triangle;  // original index, -1 on a miss
    vec2 uv;
    vec4 transmittance;  // rgb: light let through by clear triangles up to the hit (or t_max);
                         // the cutouts passed on the way do not dim it
};
layout(std430, binding = RT_BINDING_RESULTS) writeonly buffer RtHits { RtHit rt_hits[]; };
#endif

uniform uint rt_ray_count;
uniform int rt_flags;  // 0, RT_SHADOW (shadow rays) or RT_DIFFUSE (diffuse bounces)
#if !RT_ANY_HIT
uniform bool rt_has_clear;  // the scene has clear triangles (else the transmittance is 1)
#endif

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= rt_ray_count) return;
    RtQuery q = rt_queries[i];
    vec3 unused = vec3(1.0);
#if RT_ANY_HIT
    float t;
    int triangle;
    vec2 uv;
    bool hit = rt_trace(q.origin, q.dir, q.t_min, q.t_max, RT_ANY | rt_flags, t, triangle, uv,
                        unused);
    rt_occluded_out[i] = hit ? 1 : 0;
#else
    RtHit hit;
    rt_trace(q.origin, q.dir, q.t_min, q.t_max, RT_CLOSEST | rt_flags, hit.t, hit.triangle, hit.uv,
             unused);
    hit.transmittance = vec4(rt_has_clear ? rt_transmittance(q.origin, q.dir, q.t_min, hit.t,
                                                             rt_flags | RT_PASSED)
                                          : vec3(1.0), 1.0);
    rt_hits[i] = hit;
#endif
}
