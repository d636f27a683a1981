// interleave_lib.glsl used from a shader of its own (tests/core/test_shading.py): per pixel at
// u_origin + gl_FragCoord, over the indices 0..u_count-1 it uses: the first, how many, their
// sum, and the weight; and how many the strided loop from u_first visits (interleave_first).
#include "interleave_lib.glsl"

uniform ivec2 u_origin;
uniform int u_count;
uniform int u_first;

layout(location = 0) out vec4 out_uses;
layout(location = 1) out vec4 out_loop;

void main() {
    ivec2 pixel = u_origin + ivec2(gl_FragCoord.xy);
    int first = -1;
    int used = 0;
    int sum = 0;
    for (int i = 0; i < u_count; ++i) {
        if (!interleave_uses(i, pixel)) continue;
        if (first < 0) first = i;
        used += 1;
        sum += i;
    }
    out_uses = vec4(float(first), float(used), float(sum), interleave_weight());
    int visited = 0;
    int mismatches = 0;
    int start = interleave_first(u_first, pixel);
    for (int i = start; i < u_count; i += interleave_stride()) {
        visited += 1;
        if (!interleave_uses(i, pixel)) mismatches += 1;
    }
    out_loop = vec4(float(start), float(visited), float(mismatches), 0.0);
}
