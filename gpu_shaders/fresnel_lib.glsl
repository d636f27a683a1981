// Unpolarised Fresnel reflectance of a dielectric interface of relative IOR `eta` met at
// cosine `c` (Cycles' fresnel_dielectric_cos); 1 past the critical angle. Used by the
// Principled lobes and by clear surfaces.
#ifndef FRESNEL_LIB_GLSL
#define FRESNEL_LIB_GLSL
float fresnel_dielectric(float c, float eta) {
    float g2 = eta * eta - 1.0 + c * c;
    if (g2 <= 0.0) return 1.0;
    float g = sqrt(g2);
    float a = (g - c) / (g + c);
    float b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0);
    return 0.5 * a * a * (1.0 + b * b);
}

// The light one crossing of a clear surface (Material.is_clear) lets through at cosine
// `cos_i`: its colour × (1 − F), F of its Fresnel IOR `ior` (0: no loss).
vec3 clear_crossing(vec3 colour, float ior, float cos_i) {
    return ior > 0.0 ? colour * (1.0 - fresnel_dielectric(cos_i, ior)) : colour;
}
#endif
