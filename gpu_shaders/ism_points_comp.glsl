// The surface points the splat draws (ism_points_lib.glsl), written out for
// ImperfectShadowMaps.points (tests, benchmarks): x = the point in its set, y = the set.
#include "ism_points_lib.glsl"

#define ISM_BINDING_POINT_OUT 26

layout(local_size_x = 64) in;

// (triangle, barycentric weights of vertices 1 and 2 as float bits, 0) per point
layout(std430, binding = ISM_BINDING_POINT_OUT) writeonly buffer IsmPointOut { uvec4 ism_point_out[]; };

uniform int u_first_set;

void main() {
    int i = int(gl_GlobalInvocationID.x);
    int row = int(gl_GlobalInvocationID.y);
    if (i >= u_points_per_vpl) return;
    int triangle;
    vec2 bary;
    ism_surface_point(u_first_set + row, i, triangle, bary);
    ism_point_out[row * u_points_per_vpl + i] = uvec4(uint(triangle), floatBitsToUint(bary), 0u);
}
