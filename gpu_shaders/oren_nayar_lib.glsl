// Rough diffuse reflection (core/scene/oren_nayar.py): Fujii's improved Oren-Nayar lobe with
// a multiple-scattering term, per unit colour
//   A + B t + m (1 - E(mu_l)) (1 - E(mu_v)),  E(mu) = pi A + B G(mu),
// as a factor of the Lambertian lobe (1 / pi) that the diffuse light pass is made of.
#ifndef OREN_NAYAR_LIB_GLSL
#define OREN_NAYAR_LIB_GLSL
#include "common_lib.glsl"

float oren_nayar_g(float mu) {
    if (mu < 1e-6) return PI / 2.0 - 2.0 / 3.0 - mu;  // tan's limit: the Taylor expansion
    float s = sqrt(max(1.0 - mu * mu, 0.0));
    return s * (acos(min(mu, 1.0)) - 2.0 / 3.0 - s * mu)
           + 2.0 / 3.0 * (s / mu) * (1.0 - s * s * s);
}

// A pixel's lobe seen at cosine mu_v: (A, B, E(mu_v), mu_v), and m (1 - E(mu_v)) per channel
// (ms) for colour rho. code = sigma + 2 x the multiple-scattering mode (principled.py's
// specular_row: 0 none, 1 scaled by the colour as Blender 4.3-4.5, 2 OpenPBR's, 5.x).
vec4 oren_nayar_view(float code, vec3 rho, float mu_v, out vec3 ms) {
    int mode = code > 1.0 ? min(int(floor(code / 2.0)), 2) : 0;
    float s = code - 2.0 * float(mode);
    float a = 1.0 / (PI + s * (PI / 2.0 - 2.0 / 3.0)), b = s * a;
    float e_v = PI * a + b * oren_nayar_g(mu_v);
    ms = vec3(0.0);
    if (mode > 0) {
        float e_avg = PI * a + (2.0 * PI - 5.6) / 3.0 * b;
        vec3 c = clamp(rho, 0.0, 1.0);
        vec3 per_colour = c * e_avg / (1.0 - c * (1.0 - e_avg));  // rho_ms / rho
        if (mode == 1) per_colour *= c;
        ms = per_colour / (PI * (1.0 - e_avg)) * (1.0 - e_v);
    }
    return vec4(a, b, e_v, mu_v);
}

// The lobe's factor over Lambert's for light from l, seen along view.
vec3 oren_nayar_factor(vec4 lobe, vec3 ms, vec3 n, vec3 view, vec3 l) {
    float mu_l = max(dot(n, l), 0.0);
    float t = dot(l, view) - mu_l * lobe.w;
    if (t > 0.0) t /= max(max(mu_l, lobe.w), 1e-6);
    float e_l = PI * lobe.x + lobe.y * oren_nayar_g(mu_l);
    return PI * (vec3(lobe.x + lobe.y * t) + ms * (1.0 - e_l));
}

// What a VPL at a rough diffuse surface of normal n, lit from towards_light, emits towards
// out_dir per unit cosine beyond the Lambertian intensity it carries, which has the lobe's
// power: u (A + B t - E(mu_l) / pi) + v (E_avg - E(mu_out)), whose cosine-weighted integral
// is zero, for u = (flux x the diffuse colour, sigma) and v = flux x colour x m (1 - E(mu_l))
// (transport/vpl.py's VPLs.glossy, scene/geometry.py's rough_lobes).
vec3 oren_nayar_vpl_excess(vec4 u, vec3 v, vec3 n, vec3 towards_light, vec3 out_dir) {
    float a = 1.0 / (PI + u.w * (PI / 2.0 - 2.0 / 3.0)), b = u.w * a;
    float mu_l = max(dot(n, towards_light), 0.0), mu_o = max(dot(n, out_dir), 0.0);
    float t = dot(towards_light, out_dir) - mu_l * mu_o;
    if (t > 0.0) t /= max(max(mu_l, mu_o), 1e-6);
    float e_l = PI * a + b * oren_nayar_g(mu_l), e_o = PI * a + b * oren_nayar_g(mu_o);
    float e_avg = PI * a + (2.0 * PI - 5.6) / 3.0 * b;
    return u.rgb * (a + b * t - e_l / PI) + v * (e_avg - e_o);
}

#endif
