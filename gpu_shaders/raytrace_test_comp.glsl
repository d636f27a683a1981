// raytrace_lib.glsl used from a shader of its own, next to storage buffers at bindings 0 and 1
// (tests/core/test_raytrace.py): for each point, the closest hit straight up (+z) and whether
// anything lies less than 1 straight down.
#include "raytrace_lib.glsl"

layout(local_size_x = 64) in;

layout(std430, binding = 0) readonly buffer Points { vec4 points[]; };
layout(std430, binding = 1) writeonly buffer Results { ivec2 results[]; };  // (up, down)

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= points.length()) return;
    float t;
    int triangle;
    vec2 uv;
    rt_closest_hit(points[i].xyz, vec3(0.0, 0.0, 1.0), 0.0, 1.0e30, t, triangle, uv);
    bool down = rt_occluded(points[i].xyz, vec3(0.0, 0.0, -1.0), 0.0, 1.0);
    results[i] = ivec2(triangle, down ? 1 : 0);
}
