// raytrace_lib.glsl used from a shader of its own, next to storage buffers at bindings 0 and 1
// (tests/core/test_raytrace.py): for each point, the closest hit along u_direction and whether
// anything lies less than 1 the other way. The direction is a uniform, as in every shader that
// traces: NVIDIA's driver 580 missed every ray of this shader when it was a constant.
#include "raytrace_lib.glsl"

layout(local_size_x = 64) in;

layout(std430, binding = 0) readonly buffer Points { vec4 points[]; };
layout(std430, binding = 1) writeonly buffer Results { ivec2 results[]; };  // (up, down)
uniform vec3 u_direction;

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= points.length()) return;
    float t;
    int triangle;
    vec2 uv;
    rt_closest_hit(points[i].xyz, u_direction, 0.0, 1.0e30, t, triangle, uv);
    bool down = rt_occluded(points[i].xyz, -u_direction, 0.0, 1.0);
    results[i] = ivec2(triangle, down ? 1 : 0);
}
