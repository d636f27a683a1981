// Shadow hints: one ray per pixel and light sample of a ray-traced batch, so that the gather at
// every supersample (gather_frag.glsl with SHADOW_HINTS) traces only where the pixels around
// it disagree. Rendered over the pixels' g-buffer (one sample at each pixel's centre). Without
// interleaving, bit i is sample i's visibility (at most 31 samples); with it, each supersample
// gathers one sample of a K×K pattern, and bit 0 is the visibility of the sample of the
// pixel's centre supersample. Bit 31 (HINT_KNOWN) marks pixels that hold hints: surface
// pixels, and with interleaving those whose centre supersample gathers a sample, unless some
// sample is seen through a clear surface (neither lit nor shadowed: every supersample there
// traces its rays). With RT_SHADOW_LINKING all samples share the blocker sets u_blockers.
#include "lights_lib.glsl"
#include "interleave_lib.glsl"

uniform sampler2D u_position;
uniform sampler2D u_normal;
uniform sampler2D u_geometric;
uniform int u_count;   // samples in the batch

layout(location = 0) out uint out_hints;
#ifdef RT_SHADOW_LINKING
uniform uvec2 u_blockers;  // the samples' blocker sets, one for all (shadow_hints.py)
#endif

// Neither all lit (1) nor all shadowed (0): light through a clear surface.
bool partly_lit(vec3 v) {
    return any(greaterThan(v, vec3(0.0))) && any(lessThan(v, vec3(1.0)));
}

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    out_hints = 0u;
#ifdef RT_SHADOW_LINKING
    rt_blockers = u_blockers;
#endif
    if (texelFetch(u_normal, px, 0).w == 0.0) return;
    vec3 world = texelFetch(u_position, px, 0).xyz;
    vec3 geometric = texelFetch(u_geometric, px, 0).xyz;
    if (interleave_size() > 1) {
        int i = interleave_first(0, px * u_hint_factor + u_hint_factor / 2);
        if (i >= u_count) return;
        vec3 v = shadow_visibility(light_sample(i), world, geometric);
        out_hints = partly_lit(v) ? 0u : HINT_KNOWN | uint(v.r);
        return;
    }
    uint hints = HINT_KNOWN;
    for (int i = 0; i < u_count; ++i) {
        vec3 v = shadow_visibility(light_sample(i), world, geometric);
        if (partly_lit(v)) return;
        hints |= uint(v.r) << i;
    }
    out_hints = hints;
}
