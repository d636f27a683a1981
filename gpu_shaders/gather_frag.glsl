// Light of one batch of light samples, added (blending) to an accumulator in Blender's pass
// unit: irradiance / pi (the pass times DiffCol is the diffuse radiance).
// With BIAS_COMPENSATION it adds instead the light the VPL clamp removed (Kollig & Keller
// 2004): short cosine-distributed rays from the pixel find surfaces y closer than the clamp
// distance, whose outgoing radiance (this batch's light, gathered at y) arrives with weight
// 1 - d²/clamp².
// With SHADOW_HINTS (ray-traced samples) each sample's visibility comes from the pixels' hints
// where they agree (lights_lib.glsl), and from rays over the supersample's footprint elsewhere;
// with HINTS_ONLY as well, a supersample that needs a ray adds nothing and writes depth 0 for a
// second draw, with rays, that runs only there (gather.py).
// With GLOSSY a second target gets the glossy radiance towards the camera, summed over the
// same samples with the pixel's lobe from the g-buffer (bias compensation adds no glossy
// light). With COAT (some material has a clear coat) the pixel's triangle's coat reflects
// the same samples through its own lobe, with SHEEN (some material has a sheen) its sheen
// through sheen_brdf (principled_lib.glsl), which dims the coat as it dims the g-buffer's
// lobe. With VPL_GLOSSY, VPLs at glossy surfaces also emit through their lobe (lights_lib).
// With ROUGH_DIFFUSE (some material has a rough diffuse layer) each sample's diffuse light
// is weighted by the pixel's Oren-Nayar lobe over Lambert's (oren_nayar_lib.glsl), read from
// its triangle's material row.
// With TRANSLUCENT (some material lets diffuse light through) a pixel whose triangle does
// gathers the far side's light too (the normal reversed; its shadows by rays, the hints
// being the near side's) and mixes the two by its translucency; bias compensation's hits
// likewise.
// With LIGHT_LINKING the draw's samples light only the surfaces of some receiver sets
// (light_linking_lib.glsl): elsewhere, and at bias compensation's hits elsewhere, they add
// nothing. With RT_SHADOW_LINKING (ray-traced samples whose shadows some objects do not
// cast) the rays pass the triangles of the blocker sets u_blockers lacks (raytrace_lib.glsl).
#include "lights_lib.glsl"
#include "interleave_lib.glsl"
#ifdef LIGHT_LINKING
#include "light_linking_lib.glsl"
#endif
#if defined(GLOSSY) || defined(ROUGH_DIFFUSE)
uniform vec3 u_camera_position;
uniform vec3 u_camera_forward;
uniform bool u_orthographic;
#endif
#ifdef GLOSSY
#include "principled_lib.glsl"
uniform sampler2D u_lobe_a;
uniform sampler2D u_lobe_b;
uniform sampler2D u_lobe_c;
layout(location = 1) out vec4 out_glossy;
#endif
#if defined(COAT) || defined(SHEEN) || defined(ROUGH_DIFFUSE) || defined(TRANSLUCENT)
#include "materials_lib.glsl"
#endif
bool g_far_side = false;  // gathering the far side of a translucent surface
#ifdef ROUGH_DIFFUSE
#include "oren_nayar_lib.glsl"
#endif

in vec2 v_uv;

uniform sampler2D u_position;
uniform sampler2D u_normal;
uniform sampler2D u_geometric;
uniform int u_first;
uniform int u_count;

layout(location = 0) out vec4 out_light;

// The pixel's glossy lobe, its clear coat's (coat_a.w = alpha is 0 without one), its sheen's
// (principled_lib.glsl's SheenLobe; sheen_seen.rgb is 0 without one), its rough diffuse
// layer's (oren_nayar_view's; rough.x is 0 without one) and the view direction (a.w =
// alpha is 0 on diffuse pixels).
struct Lobe {
    vec4 a;
    vec4 b;
    vec4 c;
    vec4 coat_a;
    vec4 coat_b;
    vec4 sheen_seen;
    vec4 sheen_frame;
    vec4 rough;
    vec3 rough_ms;
    vec3 view;
};

const Lobe NO_LOBE = Lobe(vec4(0.0), vec4(0.0), vec4(0.0), vec4(0.0), vec4(0.0), vec4(0.0),
                          vec4(0.0), vec4(0.0), vec3(0.0), vec3(0.0));

// Sum over this draw's samples; with interleaving (u_interleave = K > 1) each pixel of a K×K
// pattern takes every K²-th sample and scales by K², so the expectation is unchanged. With a
// lobe (a.w > 0) the glossy radiance of the same samples goes into ``glossy``. With
// AREA_SHAPES, the diffuse light of a draw of an area light's samples is its exact
// unshadowed light times the fraction their shadows keep (lights_lib.glsl): with
// interleaving, the pixel's subset's shadowed light (times K²) over all the draw's samples'
// unshadowed light, which needs no shadow lookup, so that the K × K supersamples of a pixel
// together weigh each sample by its own light (a subset's own fraction would lose the light
// of the subsets below a surface's horizon).
vec3 gather(vec3 world, vec3 normal, vec3 geometric, int max_generation, Lobe lobe,
            out vec3 glossy) {
    vec3 irradiance = vec3(0.0);
    glossy = vec3(0.0);
    ivec2 px = ivec2(gl_FragCoord.xy);
#ifdef SPREAD_EDGE_RAYS
    g_spread_first = u_first;
    g_spread_count = u_count;
#endif
#ifdef AREA_SHAPES
    int run = 0;  // the draw's samples, and their unshadowed and shadowed sums
    vec3 open = vec3(0.0), shaded = vec3(0.0);
    bool subset = interleave_size() > 1;
    if (subset) {
        for (int i = u_first; i < u_first + u_count; ++i) {
            LightSample s = light_sample(i);
            if (s.generation > max_generation) continue;
            vec3 e = unshadowed_irradiance(s, world, normal);
            ++run;
            open += e;
        }
    }
#endif
    for (int i = interleave_first(u_first, px); i < u_first + u_count;
         i += interleave_stride()) {
        LightSample s = light_sample(i);
#ifdef SHADOW_HINTS
        g_hint_bit = g_far_side ? -1 : interleave_size() > 1 ? 0 : i;
#endif
#ifdef SPREAD_EDGE_RAYS
        g_spread_index = i;
#endif
        if (s.generation > max_generation) continue;
        vec3 e = unshadowed_irradiance(s, world, normal);
#ifdef AREA_SHAPES
        if (!subset) {
            ++run;
            open += e;
        }
#endif
        if (any(greaterThan(e, vec3(0.0)))) e *= shadow_visibility(s, world, geometric);
        vec3 diffuse = e;
#ifdef ROUGH_DIFFUSE
        if (lobe.rough.x > 0.0 && any(greaterThan(e, vec3(0.0)))) {
            vec3 l = s.kind == KIND_DIRECTIONAL ? -s.axis : normalize(s.position - world);
            diffuse *= oren_nayar_factor(lobe.rough, lobe.rough_ms, normal, lobe.view, l);
        }
#endif
#ifdef AREA_SHAPES
        shaded += diffuse;
#endif
        irradiance += diffuse;
#ifdef GLOSSY
        if (lobe.a.w > 0.0 && any(greaterThan(e, vec3(0.0)))) {
            vec3 l = s.kind == KIND_DIRECTIONAL ? -s.axis : normalize(s.position - world);
            glossy += e * glossy_brdf(lobe.a, lobe.b, lobe.c, normal, lobe.view, l);
#ifdef COAT
            if (lobe.coat_a.w > 0.0) {
                glossy += e * glossy_brdf(lobe.coat_a, lobe.coat_b, vec4(0.0), normal,
                                          lobe.view, l);
            }
#endif
#ifdef SHEEN
            if (lobe.sheen_seen.rgb != vec3(0.0)) {
                glossy += e * sheen_brdf(SheenLobe(lobe.sheen_seen, lobe.sheen_frame), normal, l);
            }
#endif
        }
#endif
    }
#ifdef AREA_SHAPES
    LightSample first = light_sample(u_first);  // a draw holds one area light's samples or none
    if (first.shape >= 0) {
        glossy *= interleave_weight();
        return area_light_irradiance(first.shape, shaded * interleave_weight(), open, run,
                                     first.intensity, world, normal);
    }
#endif
    float weight = interleave_weight();
    glossy *= weight;
    return irradiance * weight;
}

// The translucency of a triangle (0 for -1, no triangle, and without TRANSLUCENT).
vec3 translucency_at(int triangle) {
#ifdef TRANSLUCENT
    if (triangle >= 0) return translucency_of(triangle);
#endif
    return vec3(0.0);
}

// The diffuse light on the far side of a translucent surface (the normal reversed, without a
// glossy lobe; its shadows by rays, the shadow hints being the near side's).
vec3 far_side(vec3 world, vec3 normal, vec3 geometric, int max_generation) {
    vec3 unused;
    g_far_side = true;
    vec3 far = gather(world, -normal, -geometric, max_generation, NO_LOBE, unused);
    g_far_side = false;
    return far;
}

#ifdef BIAS_COMPENSATION
#include "raytrace_lib.glsl"
#include "materials_lib.glsl"
#include "compensation_lib.glsl"
#include "surface_lib.glsl"
uniform int u_bias_samples;
uniform int u_max_generation;  // light that may bounce once more at y

// The diffuse light at a point, without a glossy lobe: the near side's (around `normal`),
// mixed with the far side's by `through` (a translucent surface's share).
vec3 both_sides(vec3 world, vec3 normal, vec3 geometric, int max_generation, vec3 through) {
    vec3 unused;
    vec3 near = gather(world, normal, geometric, max_generation, NO_LOBE, unused);
    if (through == vec3(0.0)) return near;
    return mix(near, far_side(world, normal, geometric, max_generation), through);
}

// The hit's radiance: this batch's light gathered there, reflected by its albedo.
bool hit_radiance(vec3 origin, vec3 dir, float t, int triangle, out vec3 radiance) {
    vec3 n_y = facing_normal(triangle, dir);
#ifdef LIGHT_LINKING
    if (!lights_triangle(triangle)) {
        radiance = vec3(0.0);
        return true;
    }
#endif
    vec3 y = origin + dir * t;
    radiance = material_of(triangle).albedo.rgb / PI
               * both_sides(y, n_y, n_y, u_max_generation, translucency_at(triangle));
    return true;
}

vec3 compensation(vec3 world, vec3 normal, vec3 geometric) {
    return compensation_sum(ivec2(gl_FragCoord.xy), world + geometric * u_ray_offset, normal,
                            0, u_bias_samples) / float(u_bias_samples);
}
#endif

#ifdef RT_SHADOW_LINKING
uniform uvec2 u_blockers;  // the draw's samples' blocker sets (LightSamples.blockers)
#endif

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec4 normal = texelFetch(u_normal, px, 0);
    if (normal.w == 0.0) discard;
#ifdef RT_SHADOW_LINKING
    rt_blockers = u_blockers;
#endif
    vec3 world = texelFetch(u_position, px, 0).xyz;
    vec4 geometric_texel = texelFetch(u_geometric, px, 0);  // w: the triangle + 1
    vec3 geometric = geometric_texel.xyz;
    Lobe lobe = NO_LOBE;
#if defined(GLOSSY) || defined(ROUGH_DIFFUSE)
    lobe.view = u_orthographic ? -u_camera_forward : normalize(u_camera_position - world);
#endif
#ifdef ROUGH_DIFFUSE
    int pixel_triangle = int(geometric_texel.w + 0.5) - 1;
    if (pixel_triangle >= 0) {
        Material material = material_of(pixel_triangle);
        if (material.coat.w != 0.0) {  // the diffuse roughness
            lobe.rough = oren_nayar_view(material.coat.w, material.albedo.rgb,
                                         clamp(dot(normal.xyz, lobe.view), 0.0, 1.0),
                                         lobe.rough_ms);
        }
    }
#endif
#ifdef GLOSSY
    out_glossy = vec4(0.0);
    lobe.a = texelFetch(u_lobe_a, px, 0);
    lobe.b = texelFetch(u_lobe_b, px, 0);
    lobe.c = texelFetch(u_lobe_c, px, 0);
#if defined(COAT) || defined(SHEEN)
    int triangle = int(geometric_texel.w + 0.5) - 1;
    if (triangle >= 0 && lobe.a.w > 0.0) {
        Material material = material_of(triangle);
        float keep = 1.0;  // what the sheen leaves the coat
#ifdef SHEEN
        if (material.sheen.rgb != vec3(0.0)) {
            SheenLobe sheen = sheen_lobe(material.sheen, normal.xyz, lobe.view);
            lobe.sheen_seen = sheen.seen;
            lobe.sheen_frame = sheen.frame;
            keep = below_sheen(sheen.seen.rgb, material.coat_tint.w);
        }
#endif
        vec4 coat = material.coat;
        if (coat.x > 0.0) {
            coat_lobe(vec3(coat.x * keep), coat.y * coat.y, coat.z, lobe.coat_a, lobe.coat_b);
        }
    }
#endif
#endif
    vec3 through = translucency_at(int(geometric_texel.w + 0.5) - 1);
#ifdef BIAS_COMPENSATION
    out_light = vec4(compensation(world, normal.xyz, geometric), 0.0);
    if (through != vec3(0.0)) {
        out_light.rgb = mix(out_light.rgb, compensation(world, -normal.xyz, -geometric), through);
    }
#else
#ifdef LIGHT_LINKING
    if (!lights_triangle(int(geometric_texel.w + 0.5) - 1)) discard;
#endif
#ifdef SHADOW_HINTS
    read_shadow_hints(px);
#endif
    vec3 glossy;
    out_light = vec4(gather(world, normal.xyz, geometric, 1 << 30, lobe, glossy) / PI, 0.0);
    if (through != vec3(0.0)) {
        out_light.rgb = mix(out_light.rgb, far_side(world, normal.xyz, geometric, 1 << 30) / PI,
                            through);
    }
#ifdef GLOSSY
    out_glossy = vec4(glossy, 0.0);
#endif
#ifdef HINTS_ONLY
    gl_FragDepth = g_needs_rays ? 0.0 : 1.0;  // 0: the draw with rays takes it whole
    if (g_needs_rays) {
        out_light = vec4(0.0);
#ifdef GLOSSY
        out_glossy = vec4(0.0);
#endif
    }
#endif
#endif
}
