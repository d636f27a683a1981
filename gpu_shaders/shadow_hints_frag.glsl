// Shadow hints: one ray per pixel and light sample of a ray-traced batch, so that the gather at
// every supersample (gather_frag.glsl with SHADOW_HINTS) traces only where the pixels around
// it disagree. Rendered over the pixels' g-buffer (one sample at each pixel's centre). Without
// interleaving, bit i is sample i's visibility (at most 31 samples); with it, each supersample
// gathers one sample of a K×K pattern, and bit 0 is the visibility of the sample of the
// pixel's centre supersample. Bit 31 (HINT_KNOWN) marks pixels that hold hints: surface
// pixels, and with interleaving those whose centre supersample gathers a sample.
#include "lights_lib.glsl"
#include "interleave_lib.glsl"

uniform sampler2D u_position;
uniform sampler2D u_normal;
uniform sampler2D u_geometric;
uniform int u_count;   // samples in the batch

layout(location = 0) out uint out_hints;

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    out_hints = 0u;
    if (texelFetch(u_normal, px, 0).w == 0.0) return;
    vec3 world = texelFetch(u_position, px, 0).xyz;
    vec3 geometric = texelFetch(u_geometric, px, 0).xyz;
    if (interleave_size() > 1) {
        int i = interleave_first(0, px * u_hint_factor + u_hint_factor / 2);
        if (i >= u_count) return;
        out_hints = HINT_KNOWN | uint(shadow_visibility(light_sample(i), world, geometric));
        return;
    }
    uint hints = HINT_KNOWN;
    for (int i = 0; i < u_count; ++i) {
        hints |= uint(shadow_visibility(light_sample(i), world, geometric)) << i;
    }
    out_hints = hints;
}
