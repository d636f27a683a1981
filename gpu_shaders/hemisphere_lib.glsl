// Seeded cosine-distributed directions about a normal, per pixel and ray (bias compensation's
// rays, the Ambient Occlusion pass's).
#ifndef HEMISPHERE_LIB_GLSL
#define HEMISPHERE_LIB_GLSL
#include "common_lib.glsl"

uniform uint u_seed;

vec2 random2(uvec2 pixel, uint k) {
    uint h = pcg(pixel.x + pcg(pixel.y + pcg(k + pcg(u_seed))));
    return vec2(float(h & 0xffffu), float(h >> 16u)) / 65536.0;
}

vec3 cosine_direction(vec3 n, vec2 u) {
    vec3 t, b;
    basis_of(n, t, b);
    float r = sqrt(u.x);
    float phi = 2.0 * PI * u.y;
    return normalize(r * cos(phi) * t + r * sin(phi) * b + sqrt(max(0.0, 1.0 - u.x)) * n);
}
#endif
