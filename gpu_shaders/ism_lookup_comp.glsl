// Batch ism_visibility queries for ImperfectShadowMaps.visibility (addon/core/ism.py): one
// point per invocation, towards one VPL of the last render, against its atlas.
#include "ism_lib.glsl"

#define ISM_BINDING_VPLS 22
#define ISM_BINDING_QUERIES 23
#define ISM_BINDING_RESULTS 24

layout(local_size_x = 64) in;

struct IsmQuery {
    vec3 world;
    int vpl;
    vec3 normal;  // geometric normal
    float pad;
};

// (position, normal) per VPL
layout(std430, binding = ISM_BINDING_VPLS) readonly buffer IsmVpls { vec4 ism_vpls[]; };
layout(std430, binding = ISM_BINDING_QUERIES) readonly buffer IsmQueries { IsmQuery ism_queries[]; };
layout(std430, binding = ISM_BINDING_RESULTS) writeonly buffer IsmResults { float ism_results[]; };

uniform sampler2D u_atlas;
uniform int u_columns;
uniform float u_resolution;
uniform float u_bias;
uniform int u_count;

void main() {
    int i = int(gl_GlobalInvocationID.x);
    if (i >= u_count) return;
    IsmQuery q = ism_queries[i];
    ism_results[i] = ism_visibility(u_atlas, q.vpl, u_columns, u_resolution,
                                    ism_vpls[2 * q.vpl].xyz, ism_vpls[2 * q.vpl + 1].xyz,
                                    q.world, q.normal, u_bias);
}
