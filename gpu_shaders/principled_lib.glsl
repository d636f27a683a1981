// The Principled BSDF's reflection layers as Cycles builds them (see core/scene/principled.py,
// which computes the same on the CPU): a dielectric GGX lobe with the remapped dielectric
// Fresnel, a metallic GGX lobe with Schlick's Fresnel from the base colour, both with
// multiple-scattering compensation, over a diffuse base weighted by (1 - metallic)(1 - the
// dielectric lobe's albedo), under a clear coat and a sheen (core/scene/sheen.py: its BRDF
// times cos is colour R(mu_v) D(l), R and D's transform measured on Cycles). The g-buffer
// stores each pixel's lobe as three texels
//   a = (A, alpha), b = (B, eta), c = (C, unused here)
// so that the glossy BRDF times cos is F(h.v) D G2 / (4 n.v) with
//   F = A + B s_eta(h.v) + C (1 - h.v)^5.
#ifndef PRINCIPLED_LIB_GLSL
#define PRINCIPLED_LIB_GLSL
#include "common_lib.glsl"
#include "fresnel_lib.glsl"

// Table rows (principled.py's ROW_* constants) of the R32F table texture, E_SIZE wide.
#define E_SIZE 32
#define S_SIZE 16
#define ROW_E 0
#define ROW_EAVG 32
#define ROW_S_IOR 33
#define ROW_S5 289
#define ROW_SHEEN 305
#define SHEEN_SIZE 17  // rows of R, then of the lobe's a, then of its b

uniform sampler2D u_ggx_tables;

float table_row(int row, float x, int size) {
    float f = clamp(x, 0.0, 1.0) * float(size - 1);
    int i = min(int(floor(f)), size - 2);
    float t = f - float(i);
    return mix(texelFetch(u_ggx_tables, ivec2(i, row), 0).r,
               texelFetch(u_ggx_tables, ivec2(i + 1, row), 0).r, t);
}

float table_2d(int first, float rough, float mu, int size) {
    float f = clamp(rough, 0.0, 1.0) * float(size - 1);
    int i = min(int(floor(f)), size - 2);
    return mix(table_row(first + i, mu, size), table_row(first + i + 1, mu, size),
               f - float(i));
}

float f0_of(float eta) {
    float r = (eta - 1.0) / (eta + 1.0);
    return r * r;
}

vec3 darkening(vec3 f0, float s_avg, float e, float e_avg) {
    vec3 fss = f0 + (1.0 - f0) * s_avg;
    vec3 fms = fss * e_avg / (1.0 - fss * (1.0 - e_avg));
    return e + fms * (1.0 - e);
}

// The dielectric lobe's albedo E (F0 + (1 - F0) s_ior), without energy compensation, at
// roughness rough and cosine mu (a clear coat's: Cycles' plain GGX).
float dielectric_albedo(float rough, float eta, float mu) {
    float z = clamp(sqrt(abs((eta - 1.0) / (eta + 1.0))), 0.0, 1.0) * float(S_SIZE - 1);
    int k = min(int(floor(z)), S_SIZE - 2);
    float s = mix(table_2d(ROW_S_IOR + k * S_SIZE, rough, mu, S_SIZE),
                  table_2d(ROW_S_IOR + (k + 1) * S_SIZE, rough, mu, S_SIZE), z - float(k));
    float f0 = f0_of(eta);
    return table_2d(ROW_E, rough, mu, E_SIZE) * (f0 + (1.0 - f0) * s);
}

// The sheen's albedo R at cosine mu for its roughness.
float sheen_albedo(float rough, float mu) {
    return table_2d(ROW_SHEEN, rough, mu, SHEEN_SIZE);
}

// What a sheen that reflects ``reflected`` leaves the layers below it: where it is layered
// (the material row's layering above 0) one minus its largest channel (Cycles'
// closure_layering_weight), else all.
float below_sheen(vec3 reflected, float layering) {
    if (layering <= 0.0) return 1.0;
    return clamp(1.0 - max(reflected.r, max(reflected.g, reflected.b)), 0.0, 1.0);
}

// A pixel's sheen lobe: its colour x R at the view (rgb) and the transform's a (w), and the
// frame's x axis, the view's projection on the surface (xyz), with the transform's b (w).
struct SheenLobe {
    vec4 seen;
    vec4 frame;
};

SheenLobe sheen_lobe(vec4 sheen, vec3 n, vec3 view) {
    float mu = clamp(dot(n, view), 0.0, 1.0);
    vec3 x = view - n * dot(n, view);
    float length_x = length(x);
    x = length_x > 1e-6 ? x / length_x : abs(n.x) < 0.9 ? normalize(cross(n, vec3(1, 0, 0)))
                                                          : normalize(cross(n, vec3(0, 1, 0)));
    return SheenLobe(vec4(sheen.rgb * sheen_albedo(sheen.w, mu),
                          table_2d(ROW_SHEEN + SHEEN_SIZE, sheen.w, mu, SHEEN_SIZE)),
                     vec4(x, table_2d(ROW_SHEEN + 2 * SHEEN_SIZE, sheen.w, mu, SHEEN_SIZE)));
}

// The sheen's BRDF (radiance towards the view per unit irradiance from l): colour R D(l) /
// cos(l), D the transformed cosine a^2 cos_o / (pi |M^-1 l|^3) with cos_o = z / |M^-1 l|.
vec3 sheen_brdf(SheenLobe lobe, vec3 n, vec3 l) {
    float z = dot(n, l);
    if (z <= 0.0) return vec3(0.0);
    float a = lobe.seen.w, b = lobe.frame.w;
    vec3 y = cross(n, lobe.frame.xyz);
    vec3 o = vec3(a * dot(lobe.frame.xyz, l) + b * z, a * dot(y, l), z);
    float length2 = dot(o, o);
    return lobe.seen.rgb * (a * a / (PI * length2 * length2));
}

// Layers of a pixel seen at cosine mu: the diffuse weight (returned), the glossy albedo
// (Cycles' GlossCol, the coat's and the sheen's included) and the lobe texels, all below the
// clear coat dimmed by (1 - what it reflects) and its tint (to the power 1 / cos of the view
// refracted into it, mixed in by its weight, as Cycles), and all below a layered sheen by
// below_sheen. spec = (roughness, metallic, eta, s_avg), tint = (F0 x tint,
// flag), coat = (weight, roughness, eta, 0), coat_tint = (rgb, the sheen's layering: 0 for
// a Sheen BSDF's, 1 or 2 for the Principled BSDF's, which dims the layers below), sheen =
// (weight x tint,
// roughness) from the material table; the coat's and the sheen's own lobes are coat_lobe's and sheen_brdf's.
// below: what of the layers under the coat and sheen (and of the emission, as Cycles dims
// it) is seen through them.
vec3 principled_layers(vec3 base, vec4 spec, vec4 tint, vec4 coat, vec4 coat_tint,
                       vec4 sheen, float mu, out vec3 gloss, out vec4 lobe_a, out vec4 lobe_b,
                       out vec4 lobe_c, out vec3 below) {
    float rough = spec.x, metallic = spec.y, eta = spec.z;
    mu = clamp(mu, 1e-3, 1.0);
    float e = max(table_2d(ROW_E, rough, mu, E_SIZE), 1e-4);
    float e_avg = table_row(ROW_EAVG, rough, E_SIZE);
    float diffuse = 1.0 - metallic;
    vec3 a = vec3(0.0), b = vec3(0.0), c = vec3(0.0);
    gloss = vec3(0.0);
    if (eta != 1.0) {
        vec3 f0 = tint.rgb;
        float z = clamp(sqrt(abs((eta - 1.0) / (eta + 1.0))), 0.0, 1.0) * float(S_SIZE - 1);
        int k = min(int(floor(z)), S_SIZE - 2);
        float s = mix(table_2d(ROW_S_IOR + k * S_SIZE, rough, mu, S_SIZE),
                      table_2d(ROW_S_IOR + (k + 1) * S_SIZE, rough, mu, S_SIZE), z - float(k));
        vec3 dark = darkening(f0, spec.w, e, e_avg);
        vec3 albedo = dark * (f0 + (1.0 - f0) * s);
        diffuse *= clamp(1.0 - max(albedo.r, max(albedo.g, albedo.b)), 0.0, 1.0);
        gloss += (1.0 - metallic) * albedo;
        vec3 k_d = (1.0 - metallic) * dark / e;
        a += k_d * f0;
        b = k_d * (1.0 - f0);
    }
    if (metallic > 0.0) {
        vec3 f0 = clamp(base, 0.0, 1.0);
        vec3 dark = darkening(f0, 1.0 / 21.0, e, e_avg);
        gloss += metallic * dark * (f0 + (1.0 - f0) * table_2d(ROW_S5, rough, mu, S_SIZE));
        vec3 k_m = metallic * dark / e;
        a += k_m * f0;
        c = k_m * (1.0 - f0);
    }
    below = vec3(1.0);
    float reflected = 0.0;
    if (coat.x > 0.0) {
        reflected = coat.x * dielectric_albedo(coat.y, coat.z, mu);
        below = vec3(clamp(1.0 - reflected, 0.0, 1.0));
        if (coat_tint.rgb != vec3(1.0)) {
            float cos_refracted = sqrt(max(1.0 - (1.0 - mu * mu) / (coat.z * coat.z), 1e-12));
            below *= 1.0 + coat.x * (pow(coat_tint.rgb, vec3(1.0 / cos_refracted)) - 1.0);
        }
    }
    gloss = gloss * below + reflected;
    vec3 sheen_reflected = sheen.rgb * sheen_albedo(sheen.w, mu);
    float keep = below_sheen(sheen_reflected, coat_tint.w);
    below *= keep;
    gloss = gloss * keep + sheen_reflected;
    lobe_a = vec4(a * below, rough * rough);
    lobe_b = vec4(b * below, eta);
    lobe_c = vec4(c * below, 0.0);
    return diffuse * below;
}

// A clear coat's lobe in glossy_brdf's texels (F = weight x the real dielectric Fresnel of
// eta, the GGX alpha): lobe a and b; its c is zero. The weight is per channel for a VPL's
// coat (times its flux).
void coat_lobe(vec3 weight, float alpha, float eta, out vec4 lobe_a, out vec4 lobe_b) {
    float f0 = f0_of(eta);
    lobe_a = vec4(weight * f0, alpha);
    lobe_b = vec4(weight * (1.0 - f0), eta);
}

float smith_lambda(float alpha2, float cos_n) {
    float tan2 = max(1.0 / max(cos_n * cos_n, 1e-12) - 1.0, 0.0);
    return 0.5 * (sqrt(1.0 + alpha2 * tan2) - 1.0);
}

// Glossy BRDF times cos(light) / cos(light): the radiance towards v per unit irradiance
// arriving from l, i.e. F D G2 / (4 (n.v)(n.l)).
vec3 glossy_brdf(vec4 lobe_a, vec4 lobe_b, vec4 lobe_c, vec3 n, vec3 v, vec3 l) {
    float cos_v = dot(n, v), cos_l = dot(n, l);
    if (cos_v <= 0.0 || cos_l <= 0.0) return vec3(0.0);
    vec3 h = normalize(v + l);
    float cos_vh = clamp(dot(v, h), 0.0, 1.0);
    float cos_nh = clamp(dot(n, h), 0.0, 1.0);
    float alpha2 = lobe_a.w * lobe_a.w;
    float d = alpha2 / (PI * pow(1.0 + (alpha2 - 1.0) * cos_nh * cos_nh, 2.0));
    float g2 = 1.0 / (1.0 + smith_lambda(alpha2, cos_v) + smith_lambda(alpha2, cos_l));
    float eta = lobe_b.w;
    float s_eta = 0.0;
    if (eta != 1.0) {
        float f0 = f0_of(eta);
        s_eta = (fresnel_dielectric(cos_vh, eta) - f0) / max(1.0 - f0, 1e-6);
    }
    vec3 f = lobe_a.rgb + lobe_b.rgb * s_eta + lobe_c.rgb * pow(1.0 - cos_vh, 5.0);
    return f * d * g2 / (4.0 * cos_v * cos_l);
}

#endif
