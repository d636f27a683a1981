// Bias compensation's rays (Kollig & Keller 2004), shared by gather_frag.glsl (full: each hit
// gathers the light samples again) and near_field_frag.glsl (radiance read from the image, one
// ray per draw, with cosine_direction and random2): short cosine-distributed rays from a pixel
// find the surfaces closer than the clamp distance, and each hit's outgoing radiance, from the
// including shader's hit_radiance(), arrives with weight 1 - d²/clamp². Include after
// raytrace_lib.glsl.
#ifndef COMPENSATION_LIB_GLSL
#define COMPENSATION_LIB_GLSL
#include "hemisphere_lib.glsl"

uniform float u_clamp_distance;

// The radiance leaving the hit at ``origin + dir * t`` on ``triangle`` towards the pixel, or
// false where the including shader does not know it.
bool hit_radiance(vec3 origin, vec3 dir, float t, int triangle, out vec3 radiance);

// The weighted sum of rays first .. first + count - 1 of the pixel (the caller divides by all
// its rays).
vec3 compensation_sum(ivec2 pixel, vec3 origin, vec3 normal, int first, int count) {
    float c2 = u_clamp_distance * u_clamp_distance;
    vec3 sum = vec3(0.0);
    for (int k = first; k < first + count; ++k) {
        vec3 dir = cosine_direction(normal, random2(uvec2(pixel), uint(k)));
        float t;
        int triangle;
        vec2 uv;
        vec3 radiance;
        if (rt_diffuse_hit(origin, dir, 0.0, u_clamp_distance, t, triangle, uv)
            && hit_radiance(origin, dir, t, triangle, radiance)) {
            sum += (1.0 - t * t / c2) * radiance;
        }
    }
    return sum;
}
#endif
