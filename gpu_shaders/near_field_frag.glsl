// Bias compensation from the frame's own image: the light the VPL clamp removes (Kollig &
// Keller 2004), with the outgoing radiance of the near surfaces read from the image (as in
// Novák, Engelhardt & Dachsbacher 2011's screen-space bias compensation, but with ray-traced
// visibility). Short cosine-distributed rays from each pixel x find surfaces y closer than the
// clamp distance; where the camera sees y (y projects into the tile onto the same surface, seen
// from x's side), y's diffuse radiance albedo·(direct + indirect) in pass units arrives with
// weight 1 - d²/clamp² (with one bounce only, y's direct light: its indirect light would
// bounce twice; with more, y's indirect light is all of its VPLs', one bounce too many for the
// last generation, a share of the clamp's share). Each draw traces one ray per pixel; a hit
// the camera does not see is written out as a surface sample (position, normal facing x, and
// albedo(y) · weight / rays) whose light (direct, and with more than one bounce the VPLs')
// the renderer gathers and adds afterwards (near_field.py). Output in pass units
// (irradiance / pi), added to the indirect light before its blur. The rays start from every
// supersample; hits are looked up in the supersamples' g-buffer and direct light, and in the
// indirect light at its own resolution (per pixel or per supersample).
#include "common_lib.glsl"
#include "raytrace_lib.glsl"
#include "compensation_lib.glsl"

in vec2 v_uv;

uniform sampler2D u_position;   // the supersamples': xyz world, w view depth
uniform sampler2D u_normal;     //   shading normal, w = 1 on surfaces
uniform sampler2D u_geometric;  //   geometric normal, facing the camera
uniform sampler2D u_albedo;     // diffuse colour
uniform sampler2D u_direct;     // direct light, pass units
uniform sampler2D u_indirect;   // indirect light (clamped VPLs), pass units
#ifdef SOFT_DIRECT
uniform sampler2D u_soft_direct; // soft lights' direct light, interleaved, pass units
#endif
uniform mat4 u_view_projection; // world to the tile's clip space
uniform float u_ray_offset;
uniform float u_match_distance; // how far y may lie from the surface seen at its pixel
uniform int u_samples;      // rays per pixel in all
uniform int u_ray;          // this draw's ray

layout(location = 0) out vec4 out_light;
#ifdef GLOSSY
layout(location = 1) out vec4 out_glossy;
#endif
#include "materials_lib.glsl"
#include "surface_lib.glsl"
layout(location = HIT_POSITION_LOCATION) out vec4 out_hit_position;  // y, w = 1
layout(location = HIT_NORMAL_LOCATION) out vec4 out_hit_normal;  // facing x, w = triangle
// + 1 at a hit (as the g-buffer's geometric normal holds it: light linking's receiver set)
layout(location = HIT_FACTOR_LOCATION) out vec4 out_hit_factor;  // albedo(y) · weight / rays

// y's diffuse radiance from the image, or false where the camera does not see y from x's side.
bool hit_radiance(vec3 origin, vec3 dir, float t, int triangle, out vec3 radiance) {
    vec3 y = origin + dir * t;
    vec4 clip = u_view_projection * vec4(y, 1.0);
    if (clip.w <= 0.0) return false;
    vec2 at = clip.xy / clip.w * 0.5 + 0.5;
    ivec2 size = textureSize(u_position, 0);
    ivec2 p = ivec2(floor(at * vec2(size)));
    if (any(lessThan(p, ivec2(0))) || any(greaterThanEqual(p, size))) return false;
    if (texelFetch(u_normal, p, 0).w == 0.0) return false;
    if (distance(texelFetch(u_position, p, 0).xyz, y) > u_match_distance) return false;
    if (dot(texelFetch(u_geometric, p, 0).xyz, dir) >= 0.0) return false;
    vec3 light = texelFetch(u_direct, p, 0).rgb;
#ifdef INDIRECT_AT_HITS
    light += texelFetch(u_indirect, ivec2(floor(at * vec2(textureSize(u_indirect, 0)))), 0).rgb;
#endif
#ifdef SOFT_DIRECT
    light += texelFetch(u_soft_direct, p, 0).rgb;
#endif
    radiance = texelFetch(u_albedo, p, 0).rgb * light;
    return true;
}

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
#ifdef GLOSSY
    out_glossy = vec4(0.0);
#endif
    out_light = vec4(0.0);
    out_hit_position = out_hit_normal = out_hit_factor = vec4(0.0);
    gl_FragDepth = 0.0;  // the depth test keeps the gather at unseen hits to those (1.0)
    vec4 normal = texelFetch(u_normal, px, 0);
    if (normal.w == 0.0) return;
    vec3 origin = texelFetch(u_position, px, 0).xyz
                  + texelFetch(u_geometric, px, 0).xyz * u_ray_offset;
    vec3 dir = cosine_direction(normal.xyz, random2(uvec2(px), uint(u_ray)));
    float t;
    int triangle;
    vec2 uv;
    if (!rt_diffuse_hit(origin, dir, 0.0, u_clamp_distance, t, triangle, uv)) return;
    float weight = (1.0 - t * t / (u_clamp_distance * u_clamp_distance)) / float(u_samples);
    vec3 radiance;
    if (hit_radiance(origin, dir, t, triangle, radiance)) {
        out_light = vec4(weight * radiance, 0.0);
        return;
    }
    gl_FragDepth = 1.0;
    out_hit_position = vec4(origin + dir * t, 1.0);
    out_hit_normal = vec4(facing_normal(triangle, dir), float(triangle + 1));
    out_hit_factor = vec4(material_of(triangle).albedo.rgb * weight, 0.0);
}
