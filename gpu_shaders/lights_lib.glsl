// The light-sample table (a RGBA32F texture, 5 texels per sample) and the shadow-map lookup.
// With VPL_GLOSSY the table has 10 texels per sample: texel 4's w flags a VPL at a glossy
// surface, whose texels 5-9 are its GGX lobe scaled by the incident flux (principled_lib's
// lobe_a/b/c), the direction its light came from with its clear coat's eta, and the coat's
// weight times the flux with its alpha (transport/vpl.py's VPLs.glossy). With VPL_ROUGH too
// the table has 12 texels per sample: texels 10-11 are a VPL's rough diffuse lobe (its
// sigma in texel 10's w, 0 for a smooth surface), whose light leaves through its Oren-Nayar
// lobe instead of a cosine.
// A negative texel 4 w, -(k + 1), marks a sample of area light k of the AREA_SHAPES table.
// Texel 4's z is the spread's normalisation where texel 4's y (its tan) is positive, else the
// radius of the sample's light's Soft Falloff (transport/lights.py soft_falloff_radius).
// Texel 0's w is the kind + 4 × (the sample's light in the IES profile tables + 1).
#ifndef LIGHTS_LIB_GLSL
#define LIGHTS_LIB_GLSL
#include "common_lib.glsl"
#ifdef VPL_GLOSSY
#include "principled_lib.glsl"
#endif
#ifdef VPL_ROUGH
#include "oren_nayar_lib.glsl"
#endif

struct LightSample {
    vec3 position;      // world position; for directional samples unused
    int kind;
    vec3 axis;          // direction of travel (spot, sun, world) or emitter normal
    float spot_cos;     // cosine of the half cone angle; <= -1 means no spot mask
    vec3 intensity;     // W/sr (omni, peak of cosine emitters) or W/m^2 (directional)
    float spot_smooth;  // 1 / ((1 - spot_cos) * blend); 0 means a hard edge
    int tile;           // first atlas tile of its shadow map, -1 for no shadow
    float resolution;   // texels per tile edge
    float near;
    float far;
    int generation;     // bounces the light has made: 0 for lights, k for k-th bounce VPLs
    float spread_tan;   // area-light spread: tan of the half angle, 0 for none
    float spread_norm;  // Cycles' normalisation of the spread (keeps the light's power)
    int shape;          // its area light in the AREA_SHAPES table, -1 for none
    float soft_radius;  // Soft Falloff: a sphere light's radius, 0 for none
    int profile;        // its light in the IES profile tables (LIGHT_PROFILES), -1 for none
#ifdef VPL_GLOSSY
    vec4 lobe_a;        // flux x A, alpha (0: no glossy emission)
    vec4 lobe_b;        // flux x B, eta
    vec4 lobe_c;        // flux x C
    vec3 towards_light; // where the VPL's light came from
    float coat_eta;     // its clear coat's IOR
    vec4 coat;          // flux x the coat's weight, its alpha (0: no coat)
    vec4 rough;         // flux x the diffuse colour, sigma (0: no rough diffuse lobe)
    vec3 rough_ms;      // flux x the colour x m (1 - E(mu_l)) (oren_nayar_vpl_excess)
#endif
};

uniform sampler2D u_light_table;

LightSample light_sample(int index) {
    vec4 t0 = texelFetch(u_light_table, ivec2(0, index), 0);
    vec4 t1 = texelFetch(u_light_table, ivec2(1, index), 0);
    vec4 t2 = texelFetch(u_light_table, ivec2(2, index), 0);
    vec4 t3 = texelFetch(u_light_table, ivec2(3, index), 0);
    vec4 t4 = texelFetch(u_light_table, ivec2(4, index), 0);
#ifdef VPL_GLOSSY
    vec4 a = vec4(0.0), b = vec4(0.0), c = vec4(0.0), d = vec4(0.0), e = vec4(0.0);
    vec4 f = vec4(0.0), g = vec4(0.0);
    if (t4.w > 0.0) {
        a = texelFetch(u_light_table, ivec2(5, index), 0);
        b = texelFetch(u_light_table, ivec2(6, index), 0);
        c = texelFetch(u_light_table, ivec2(7, index), 0);
        d = texelFetch(u_light_table, ivec2(8, index), 0);
        e = texelFetch(u_light_table, ivec2(9, index), 0);
#ifdef VPL_ROUGH
        f = texelFetch(u_light_table, ivec2(10, index), 0);
        g = texelFetch(u_light_table, ivec2(11, index), 0);
#endif
    }
    return LightSample(t0.xyz, int(t0.w) & 3, t1.xyz, t1.w, t2.xyz, t2.w, int(t3.x), t3.y, t3.z,
                       t3.w, int(t4.x), t4.y, t4.z, int(max(-t4.w, 0.0)) - 1,
                       t4.y > 0.0 ? 0.0 : t4.z, (int(t0.w) >> 2) - 1, a, b, c, d.xyz, d.w,
                       e, f, g.rgb);
#else
    return LightSample(t0.xyz, int(t0.w) & 3, t1.xyz, t1.w, t2.xyz, t2.w, int(t3.x), t3.y, t3.z,
                       t3.w, int(t4.x), t4.y, t4.z, int(max(-t4.w, 0.0)) - 1,
                       t4.y > 0.0 ? 0.0 : t4.z, (int(t0.w) >> 2) - 1);
#endif
}

// Squared distances below this are clamped: bounds the 1/d² singularity of VPLs (the clamp
// setting) and keeps any sample lying on a surface finite.
uniform float u_min_distance2;

#ifdef AREA_SHAPES
// Area lights' outlines (transport/lights.py AreaShapes) for the ratio estimator of their
// light (Heitz, Hill & McGuire 2018): the light's exact unshadowed irradiance times the
// fraction its samples' shadowed point estimates keep of their unshadowed ones, so unshadowed
// light is exact and the samples give only the fraction in shadow.
uniform sampler2D u_area_shapes;  // rows of AREA_SHAPES_WIDTH texels (a power of two)

vec4 area_texel(int i) {
    return texelFetch(u_area_shapes, ivec2(i & (AREA_SHAPES_WIDTH - 1), i / AREA_SHAPES_WIDTH),
                      0);
}

// Twice the projected solid angle of a spherical polygon's edge a -> b (not unit vectors),
// signed by the winding: the edge's angle θ times n · its plane's unit normal (Lambert), with
// θ / sin θ from the rational fit of Heitz et al. 2016 (LTC, which fits θ / (2π sin θ)),
// avoiding atan.
float outline_edge(vec3 a, vec3 b, vec3 n) {
    if (a == vec3(0.0) || b == vec3(0.0)) return 0.0;
    a = normalize(a);
    b = normalize(b);
    float x = dot(a, b);
    float y = abs(x);
    float v = (0.8543985 + (0.4965155 + 0.0145206 * y) * y) / (3.4175940 + (4.1616724 + y) * y);
    float angle_over_sin = x > 0.0 ? v : 0.5 * inversesqrt(max(1.0 - x * x, 1e-7)) - v;
    return 2.0 * PI * angle_over_sin * dot(cross(a, b), n);
}

// The projected solid angle (∫ cos dω) of the convex outline points first .. first + count - 1
// seen from x with normal n, clipped at x's horizon.
float outline_projected_solid_angle(int first, int count, vec3 x, vec3 n) {
    float sum = 0.0;
    vec3 previous = area_texel(first + count - 1).xyz - x;
    float h_previous = dot(previous, n);
    vec3 leaves = vec3(0.0), enters = vec3(0.0);  // where the outline crosses the horizon
    for (int i = first; i < first + count; ++i) {
        vec3 current = area_texel(i).xyz - x;
        float h = dot(current, n);
        if (h_previous > 0.0 && h > 0.0) {
            sum += outline_edge(previous, current, n);
        } else if (h_previous > 0.0 || h > 0.0) {
            vec3 crossing = mix(previous, current, h_previous / (h_previous - h));
            if (h_previous > 0.0) {
                sum += outline_edge(previous, crossing, n);
                leaves = crossing;
            } else {
                sum += outline_edge(crossing, current, n);
                enters = crossing;
            }
        }
        previous = current;
        h_previous = h;
    }
    return 0.5 * abs(sum + outline_edge(leaves, enters, n));
}

// Area light `shape`'s irradiance at x (normal n) from `run` of its samples whose unshadowed
// point estimates sum to `open` and shadowed ones to `shaded` (per channel: clear surfaces
// tint the shadowed ones), `intensity` being each sample's: the light's exact unshadowed
// irradiance times shaded / open, times the run's share of its samples. Called once per draw: llvmpipe runs both sides
// of a branch, so inside the loop it would cost every sample.
vec3 area_light_irradiance(int shape, vec3 shaded, vec3 open, int run, vec3 intensity,
                           vec3 x, vec3 n) {
    if (!(open.r + open.g + open.b > 0.0)) return vec3(0.0);
    vec4 header = area_texel(shape);  // first outline point, points, samples, outline area
    // radiance = intensity × samples / area, and the run's share of the samples run / samples
    float exact = outline_projected_solid_angle(int(header.x), int(header.y), x, n)
                  * float(run) / max(header.w, 1e-30);
    return intensity * exact * (shaded / max(open, vec3(1.0e-30)));
}
#endif

// Cycles' spot mask: smoothstep of the cosine past the cone edge, scaled by the blend.
float spot_mask(LightSample s, vec3 from_light) {
    if (s.spot_cos <= -1.0) return 1.0;
    float c = dot(from_light, s.axis);
    if (s.spot_smooth <= 0.0) return c > s.spot_cos ? 1.0 : 0.0;
    float x = clamp((c - s.spot_cos) * s.spot_smooth, 0.0, 1.0);
    return x * x * (3.0 - 2.0 * x);
}

// Cycles' area-light spread (a soft box's grid of slats): max((tan a - tan θ) norm, 0).
float spread(LightSample s, vec3 from_light) {
    if (s.spread_tan <= 0.0) return 1.0;
    float c = dot(from_light, s.axis);
    if (c <= 0.0) return 0.0;
    float tan_theta = sqrt(max(1.0 - c * c, 0.0)) / c;
    return max((s.spread_tan - tan_theta) * s.spread_norm, 0.0);
}

#ifdef LIGHT_PROFILES
// IES profiles (transport/light_profiles.py): three texels per profiled light, the rows of its
// world-to-light rotation (texel 0's w: its profile's first row in the grid), and the
// profiles sampled every 1° of vertical angle (columns) and PROFILE_ROWS rows of horizontal
// angle from 0° to 360°, read bilinearly. The angles are Cycles' IES Texture node's.
uniform sampler2D u_profile_frames;
uniform sampler2D u_profile_grid;

float light_profile(int light, vec3 from_light) {
    if (light < 0) return 1.0;
    vec4 row0 = texelFetch(u_profile_frames, ivec2(0, light), 0);
    vec3 local = vec3(dot(row0.xyz, from_light),
                      dot(texelFetch(u_profile_frames, ivec2(1, light), 0).xyz, from_light),
                      dot(texelFetch(u_profile_frames, ivec2(2, light), 0).xyz, from_light));
    float v = acos(clamp(-local.z, -1.0, 1.0));
    float h = (local.x == 0.0 && local.y == 0.0) ? PI : atan(local.x, local.y) + PI;
    vec2 size = vec2(textureSize(u_profile_grid, 0));
    vec2 texel = vec2(v / PI * (size.x - 1.0),
                      row0.w + h / (2.0 * PI) * float(PROFILE_ROWS - 1)) + 0.5;
    return texture(u_profile_grid, texel / size).r;
}
#endif

// Radiant intensity (W/sr) of a non-directional sample towards a unit direction; a glossy
// VPL adds its light reflected by its lobe, flux x f_glossy(towards_light, from_light) x cos,
// and a VPL at a rough diffuse surface redistributes its diffuse light by its lobe.
vec3 emitted_intensity(LightSample s, vec3 from_light) {
    float falloff = 1.0;
    if (s.kind == KIND_COSINE) falloff = max(dot(from_light, s.axis), 0.0) * spread(s, from_light);
    else if (s.kind == KIND_COSINE2) falloff = abs(dot(from_light, s.axis));
#ifdef LIGHT_PROFILES
    falloff *= light_profile(s.profile, from_light);
#endif
#ifdef VPL_GLOSSY
    vec3 diffuse = s.intensity * falloff * spot_mask(s, from_light);
#ifdef VPL_ROUGH
    if (s.rough.w > 0.0) {
        diffuse = max(diffuse + max(dot(from_light, s.axis), 0.0) * oren_nayar_vpl_excess(
            s.rough, s.rough_ms, s.axis, s.towards_light, from_light), 0.0);
    }
#endif
    vec3 glossy = vec3(0.0);
    if (s.lobe_a.w > 0.0) {
        glossy = glossy_brdf(s.lobe_a, s.lobe_b, s.lobe_c, s.axis, from_light, s.towards_light);
        if (s.coat.w > 0.0) {
            vec4 coat_a, coat_b;
            coat_lobe(s.coat.rgb, s.coat.w, s.coat_eta, coat_a, coat_b);
            glossy += glossy_brdf(coat_a, coat_b, vec4(0.0), s.axis, from_light,
                                  s.towards_light);
        }
        glossy *= max(dot(from_light, s.axis), 0.0);
    }
    return diffuse + glossy;
#else
    return s.intensity * falloff * spot_mask(s, from_light);
#endif
}

uniform sampler2D u_shadow_atlas;
uniform int u_atlas_columns;
uniform vec3 u_scene_centre;
uniform float u_scene_radius;
uniform float u_shadow_bias;   // receiver offset in texels
// A point sample's receiver moves SHADOW_NORMAL_SHARE × u_shadow_bias texels along its
// normal and SHADOW_LIGHT_SHARE × u_shadow_bias texels towards the light. Along the normal
// the offset clears the receiver's own surface but moves a shadow edge by offset /
// tan(elevation) where light grazes (all of it along the normal made the Cornell box's
// penumbra on the red wall 27-31 % dark); towards the light it leaves the edge in place but
// crosses zero-thickness walls next to their joints (1 + tan of the incidence angle times
// u_shadow_bias let 10 % of a closed cube's outside light in). The shares keep the grazing
// edge within 0.6 texel (tests/core/test_direct_light.py) and the cube's leak near the
// normal offset's (tests/stability/test_bad_input.py). Directional maps, whose texels span the whole scene,
// keep the offset along the normal.
const float SHADOW_NORMAL_SHARE = 0.5;
const float SHADOW_LIGHT_SHARE = 0.25;
uniform float u_ism_bias;      // imperfect shadow maps: receiver offset in texels

// Percentage-closer lookup (2x2 bilinear taps) of one tile at texel coordinates `texel`.
float shadow_taps(int tile, float resolution, vec2 texel, float receiver, float tolerance) {
    ivec2 origin = ivec2(tile % u_atlas_columns, tile / u_atlas_columns) * int(resolution);
    vec2 p = texel - 0.5;
    vec2 f = fract(p);
    ivec2 base = ivec2(floor(p));
    float lit = 0.0;
    for (int j = 0; j < 2; ++j) {
        for (int i = 0; i < 2; ++i) {
            ivec2 q = clamp(base + ivec2(i, j), ivec2(0), ivec2(int(resolution) - 1));
            float occluder = texelFetch(u_shadow_atlas, origin + q, 0).r;
            float w = (i == 0 ? 1.0 - f.x : f.x) * (j == 0 ? 1.0 - f.y : f.y);
            lit += w * (receiver <= occluder + tolerance ? 1.0 : 0.0);
        }
    }
    return lit;
}

uniform float u_ray_offset;  // how far rays start off the surface, scene-relative

#ifdef EXACT_VISIBILITY
#include "raytrace_lib.glsl"

#ifdef SHADOW_HINTS
// Shadow hints (shadow_hints_frag.glsl): each pixel's visibility of the batch's samples. A
// supersample whose 3×3 pixels all know a sample's visibility and agree on it takes that
// instead of tracing; the others (shadow edges, penumbrae, silhouettes) trace EDGE_RAYS rays
// from 2×2 points of the supersample's cell, carried onto the tangent plane of its surface by
// camera rays, so that a shadow edge crossing the cell gets a fractional visibility (the box
// filter's coverage) instead of all or nothing.
uniform usampler2D u_shadow_hints;
uniform int u_hint_factor;  // supersamples per pixel edge
uniform mat4 u_inverse_view_projection;  // the tile's clip space to world
uniform vec2 u_tile_size;   // supersamples
const uint HINT_KNOWN = 1u << 31;
const int EDGE_RAYS = 4;
const vec2 EDGE_OFFSETS[EDGE_RAYS] = vec2[](vec2(-0.25, -0.25), vec2(0.25, -0.25),
                                           vec2(-0.25, 0.25), vec2(0.25, 0.25));
uint g_hints_agreed = 0u;   // bits of samples the 3×3 pixels agree on
uint g_hints_lit = 0u;      // their visibility
int g_hint_bit = -1;        // the sample being gathered: its bit, or -1 (no hint: one ray)
#ifdef SPREAD_EDGE_RAYS
// A sun's angle samples, interleaved (one a supersample): where a supersample traces its edge
// rays, ray k takes the sample k quarters of the draw's count after the gathered one (cyclic),
// so a penumbra gets four of the sun's directions per supersample instead of one, for no more
// rays. The samples differ in direction only (a sun's light is the same from each).
int g_spread_first = 0;     // the draw's first sample, how many it holds, and the one gathered
int g_spread_count = 1;
int g_spread_index = 0;
#endif
bool g_footprint_known = false;
vec3 g_footprint_x = vec3(0.0);  // one supersample's step across the tangent plane, in x
vec3 g_footprint_y = vec3(0.0);  //   and in y (zero where the camera grazes the surface)

// Where the camera ray through tile coordinate `at` (in supersamples) meets the plane
// through `p` with normal `n`; `p` itself where the ray grazes the plane.
vec3 on_tangent_plane(vec2 at, vec3 p, vec3 n) {
    vec2 ndc = at / u_tile_size * 2.0 - 1.0;
    vec4 near = u_inverse_view_projection * vec4(ndc, -1.0, 1.0);
    vec4 far = u_inverse_view_projection * vec4(ndc, 1.0, 1.0);
    vec3 origin = near.xyz / near.w;
    vec3 dir = normalize(far.xyz / far.w - origin);
    float facing = dot(n, dir);
    if (!(abs(facing) > 0.05)) return p;  // grazing (or not finite)
    return origin + dir * (dot(n, p - origin) / facing);
}

// g_footprint_x and g_footprint_y of this fragment's supersample, at its first shadow edge.
void find_footprint(vec3 world, vec3 geometric_normal) {
    vec2 centre = gl_FragCoord.xy;
    vec3 here = on_tangent_plane(centre, world, geometric_normal);
    g_footprint_x = on_tangent_plane(centre + vec2(1.0, 0.0), world, geometric_normal) - here;
    g_footprint_y = on_tangent_plane(centre + vec2(0.0, 1.0), world, geometric_normal) - here;
    if (any(isnan(g_footprint_x + g_footprint_y)) || any(isinf(g_footprint_x + g_footprint_y))) {
        g_footprint_x = g_footprint_y = vec3(0.0);
    }
    g_footprint_known = true;
}

void read_shadow_hints(ivec2 supersample) {
    ivec2 pixel = supersample / u_hint_factor;
    ivec2 last = textureSize(u_shadow_hints, 0) - 1;
    uint all_set = ~0u, any_set = 0u;
    for (int j = 0; j < 9; ++j) {
        uint h = texelFetch(u_shadow_hints, clamp(pixel + ivec2(j % 3, j / 3) - 1, ivec2(0),
                                                  last), 0).r;
        all_set &= h;
        any_set |= h;
    }
    g_hints_agreed = (all_set & HINT_KNOWN) != 0u ? ~(all_set ^ any_set) : 0u;
    g_hints_lit = all_set;
}
#endif


// Share of u_ray_offset a shadow ray starts off the surface along its normal; it skips the
// rest along itself (t_min). An offset along the normal alone moves every shadow edge by
// offset / tan(elevation): the interior's sun-patch edges lay 0.13 px into the shadow.
const float SHADOW_RAY_NORMAL_SHARE = 0.1;

// One ray: the light let through on the segment from `world` to the sample (or along its
// direction): 1 where nothing is in the way, 0 where something opaque is, clear surfaces'
// colour and Fresnel loss between. A light's sample casts a shadow ray (shadowless objects let
// it through, as Cycles' shadow rays); a VPL's is a diffuse bounce (diffuse-hidden ones do).
vec3 traced_visibility(LightSample s, vec3 world, vec3 geometric_normal) {
    vec3 origin = world + geometric_normal * (u_ray_offset * SHADOW_RAY_NORMAL_SHARE);
    float t_min = u_ray_offset;
    int flags = s.generation == 0 ? RT_SHADOW : RT_DIFFUSE;
    if (s.kind == KIND_DIRECTIONAL) {
        return rt_transmittance(origin, -s.axis, t_min, 3.0e38, flags);
    }
    vec3 to_light = s.position - origin;
    float distance = length(to_light);
    float t_max = distance * (1.0 - 1e-4) - u_ray_offset;
    if (t_max <= t_min) return vec3(1.0);
    return rt_transmittance(origin, to_light / distance, t_min, t_max, flags);
}

#ifdef HINTS_ONLY
// The hints-only draw (gather.py) leaves a supersample that needs a ray to the draw after it,
// whose shader has the rays: compiled in, even where no fragment runs them, ray code makes
// every fragment of llvmpipe's gather several times slower.
bool g_needs_rays = false;
#endif

// Ray-traced visibility of the sample from `world`, in [0, 1] per channel (clear surfaces
// tint it).
vec3 shadow_visibility(LightSample s, vec3 world, vec3 geometric_normal) {
    if (s.tile < 0) return vec3(1.0);  // the light casts no shadow
#ifdef SHADOW_HINTS
    if (g_hint_bit >= 0) {
        if (((g_hints_agreed >> g_hint_bit) & 1u) != 0u) {
            return vec3(float((g_hints_lit >> g_hint_bit) & 1u));
        }
#ifdef HINTS_ONLY
        g_needs_rays = true;
        return vec3(0.0);
#else
        if (!g_footprint_known) find_footprint(world, geometric_normal);
        vec3 lit = vec3(0.0);
        for (int k = 0; k < EDGE_RAYS; ++k) {
            vec3 at = world + g_footprint_x * EDGE_OFFSETS[k].x
                      + g_footprint_y * EDGE_OFFSETS[k].y;
#ifdef SPREAD_EDGE_RAYS
            int step = max(g_spread_count / EDGE_RAYS, 1);
            LightSample spread = light_sample(g_spread_first + (g_spread_index - g_spread_first
                                                                + k * step) % g_spread_count);
            lit += traced_visibility(spread, at, geometric_normal);
#else
            lit += traced_visibility(s, at, geometric_normal);
#endif
        }
        return lit / float(EDGE_RAYS);
#endif
    }
#endif
#ifdef HINTS_ONLY
    g_needs_rays = true;
    return vec3(0.0);
#else
    return traced_visibility(s, world, geometric_normal);
#endif
}
#elif defined(ISM_VISIBILITY)
#include "ism_lib.glsl"

// Imperfect shadow map of a sample: tile `s.tile` of the atlas holds its paraboloid depth map
// (orthographic for directional samples).
float shadow_visibility(LightSample s, vec3 world, vec3 geometric_normal) {
    if (s.kind == KIND_DIRECTIONAL) {
        return ism_visibility_directional(u_shadow_atlas, s.tile, u_atlas_columns, s.resolution,
                                          s.axis, u_scene_centre, u_scene_radius, world,
                                          geometric_normal, u_ism_bias);
    }
    return ism_visibility(u_shadow_atlas, s.tile, u_atlas_columns, s.resolution, s.position,
                          s.axis, world, geometric_normal, u_ism_bias);
}
#else
#ifdef CLEAR_SHADOWS
// The atlas's clear layer (shadow_clear_frag.glsl): what clear surfaces nearer the light than
// the receiver let through, at the texel the receiver falls in.
uniform sampler2D u_clear_atlas;

vec3 through_clear(int tile, float resolution, vec2 texel, float receiver, float tolerance) {
    ivec2 origin = ivec2(tile % u_atlas_columns, tile / u_atlas_columns) * int(resolution);
    ivec2 q = clamp(ivec2(floor(texel)), ivec2(0), ivec2(int(resolution) - 1));
    vec4 clear = texelFetch(u_clear_atlas, origin + q, 0);
    return receiver > clear.a + tolerance ? clear.rgb : vec3(1.0);
}
#endif

// The light of the sample reaching `world` (receiver offset by `bias` texels): the maps' lit
// fraction, dimmed by clear surfaces on the way with CLEAR_SHADOWS.
vec3 mapped_visibility(int tile, float resolution, vec2 texel, float receiver, float tolerance) {
    float lit = shadow_taps(tile, resolution, texel, receiver, tolerance);
#ifdef CLEAR_SHADOWS
    if (lit > 0.0) return lit * through_clear(tile, resolution, texel, receiver, tolerance);
#endif
    return vec3(lit);
}

vec3 shadow_visibility(LightSample s, vec3 world, vec3 geometric_normal) {
    if (s.tile < 0) return vec3(1.0);
    if (s.kind == KIND_DIRECTIONAL) {
        float texel_size = 2.0 * u_scene_radius / s.resolution;
        vec3 p = world + geometric_normal * (u_shadow_bias * texel_size);
        vec4 clip = directional_clip(p, s.axis, u_scene_centre, u_scene_radius);
        vec2 texel = (clip.xy * 0.5 + 0.5) * s.resolution;
        float receiver = directional_depth(p, s.axis, u_scene_centre, u_scene_radius);
        return mapped_visibility(s.tile, s.resolution, texel, receiver, 0.5 * texel_size);
    }
    float distance = length(world - s.position);
    float texel_size = 2.0 * distance / s.resolution;
    vec3 to_light = (s.position - world) / max(distance, 1e-30);
    float offset = u_shadow_bias * texel_size;
    vec3 p = world + geometric_normal * (SHADOW_NORMAL_SHARE * offset)
             + to_light * (SHADOW_LIGHT_SHARE * offset);
    vec3 v = p - s.position;
    int face = cube_face_of(v);
    vec3 local = CUBE_FACE_ROTATION[face] * v;
    vec2 texel = (local.xy / -local.z * 0.5 + 0.5) * s.resolution;
    return mapped_visibility(s.tile + face, s.resolution, texel, length(v), 0.5 * texel_size);
}
#endif

// Irradiance (W/m^2) at a surface point from one sample, before its shadow
// (shadow_visibility).
vec3 unshadowed_irradiance(LightSample s, vec3 world, vec3 normal) {
    if (s.kind == KIND_DIRECTIONAL) return s.intensity * max(dot(normal, -s.axis), 0.0);
    vec3 to_light = s.position - world;
    float distance2 = dot(to_light, to_light);
    if (distance2 <= 0.0) return vec3(0.0);
    vec3 dir = to_light * inversesqrt(distance2);
    float cos_receiver = dot(normal, dir);
    if (cos_receiver <= 0.0) return vec3(0.0);
    vec3 irradiance = emitted_intensity(s, -dir) * cos_receiver / max(distance2, u_min_distance2);
    if (s.soft_radius > 0.0) {  // a sample on the sphere: its centre lies soft_radius inside
        vec3 to_centre = s.position - s.soft_radius * s.axis - world;
        float centre2 = dot(to_centre, to_centre);
        irradiance *= centre2 / (centre2 + s.soft_radius * s.soft_radius);
    }
    return irradiance;
}
#endif
