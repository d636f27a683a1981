// One axis of the geometry-aware (cross-bilateral) blur that removes the interleaved-sampling
// pattern from the indirect light (addon/core/shading.py runs it along x, then along y).
// Taps j = -r..r carry weight 1, the two end taps 1/2: the window spans 2r pixels, so on a flat
// surface a pattern of period K, with K dividing 2r, averages out exactly. Each tap is further
// weighted by the g-buffer: the similarity of its normal, pow(max(n_p·n_q, 0), u_normal_power),
// and its distance from the centre's tangent plane relative to the centre's view depth,
// exp(-(|(x_q - x_p)·n_p| / (depth_p · u_plane_tolerance))²). Background pixels (normal.w = 0)
// keep their value and never contribute. SOURCES light textures (default 1) are blurred at
// once, into as many outputs, with the same weights.

#ifndef SOURCES
#define SOURCES 1
#endif

uniform sampler2D u_source[SOURCES];  // RGBA32F light
uniform sampler2D u_position;  // xyz world position, w view depth
uniform sampler2D u_normal;    // xyz shading normal, w 1 on surfaces
uniform ivec2 u_axis;          // (1, 0) or (0, 1)
uniform int u_radius;
uniform float u_normal_power;
uniform float u_plane_tolerance;

layout(location = 0) out vec4 out_light[SOURCES];

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    ivec2 size = textureSize(u_normal, 0);
    vec4 normal = texelFetch(u_normal, p, 0);
    vec4 sum[SOURCES];
    for (int s = 0; s < SOURCES; ++s) sum[s] = texelFetch(u_source[s], p, 0);
    if (normal.w == 0.0) {
        for (int s = 0; s < SOURCES; ++s) out_light[s] = sum[s];
        return;
    }
    vec4 position = texelFetch(u_position, p, 0);
    float plane_scale = 1.0 / max(abs(position.w) * u_plane_tolerance, 1e-30);
    float total = 1.0;
    for (int j = -u_radius; j <= u_radius; ++j) {
        ivec2 q = p + j * u_axis;
        if (j == 0 || any(lessThan(q, ivec2(0))) || any(greaterThanEqual(q, size))) continue;
        vec4 n_q = texelFetch(u_normal, q, 0);
        if (n_q.w == 0.0) continue;
        float plane = dot(texelFetch(u_position, q, 0).xyz - position.xyz, normal.xyz)
                      * plane_scale;
        float weight = (abs(j) == u_radius ? 0.5 : 1.0)
                       * pow(max(dot(normal.xyz, n_q.xyz), 0.0), u_normal_power)
                       * exp(-plane * plane);
        for (int s = 0; s < SOURCES; ++s) sum[s] += weight * texelFetch(u_source[s], q, 0);
        total += weight;
    }
    for (int s = 0; s < SOURCES; ++s) out_light[s] = sum[s] / total;
}
