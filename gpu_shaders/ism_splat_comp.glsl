// Imperfect shadow maps, step 2 (addon/core/gpu/ism.py): splat every VPL's own set of surface
// points (drawn here, ism_points_lib.glsl) into its paraboloid map. One invocation per (point,
// VPL): x = the point in the VPL's set, y = the VPL, whose atlas tile names its set (a partial
// update renders a few tiles). The point's position comes from the current triangle vertices,
// so points follow moved and deformed triangles. Depths are distances (positive floats, whose
// bits compare like the floats as uints), kept with imageAtomicMin over the texels of the
// point's footprint: the ellipse its disc projects to (a square in directional maps). A point on
// a triangle diffuse bounces pass (its vertices' w = 1) is splatted as ISM_FAR: lit, but not a
// hole for pull-push to fill with nearer surfaces' depths.
#include "ism_lib.glsl"
#include "ism_points_lib.glsl"

#define ISM_BINDING_VERTICES 21
#define ISM_BINDING_VPLS 22

layout(local_size_x = 64) in;

// three per triangle; w 1 on triangles diffuse bounces pass
layout(std430, binding = ISM_BINDING_VERTICES) readonly buffer IsmVertices { vec4 ism_vertices[]; };
// (position, directional flag), (normal or direction of travel, atlas tile) per VPL
layout(std430, binding = ISM_BINDING_VPLS) readonly buffer IsmVpls { vec4 ism_vpls[]; };

layout(r32ui, binding = 0) uniform uimage2D u_splat;

uniform int u_columns;
uniform int u_resolution;
uniform float u_point_area;      // surface area each point stands for
uniform float u_footprint_scale; // footprint disc radius / that of the point's share of the
                                 // surface (directional: square side / projected area's side)
uniform int u_max_footprint;     // largest footprint side, texels
uniform int u_first_row;         // the first VPL of this dispatch
uniform vec3 u_scene_centre;     // bounding sphere of the scene, for directional maps
uniform float u_scene_radius;

// A footprint side of `side` texels rounded up or down at random so that the expected area is
// side², kept within 1 .. u_max_footprint.
int random_side(float side, uint id) {
    float low = floor(side);
    float up = (side * side - low * low) / (2.0 * low + 1.0);  // P(round up): mean area side^2
    return clamp(int(low) + (ism_unit(pcg(id)) < up ? 1 : 0), 1, u_max_footprint);
}

// Depth of the texel whose centre is at `uv`: the distance along its ray (in the VPL's frame
// t, b, n) to the plane through the point with normal `surface`, whose ray at the point's own
// direction `d` has length `distance`. Kept within a factor 2 of `distance`, and `distance`
// where the ray does not meet the plane in front (a splat is a small disc, not the plane).
float plane_depth(vec3 t, vec3 b, vec3 n, vec2 uv, vec3 surface, vec3 d, float distance) {
    vec3 local = ism_local_direction(uv);
    float cos_texel = dot(surface, local.x * t + local.y * b + local.z * n);
    float cos_point = dot(surface, d);
    if (cos_texel * cos_point <= 0.0) return distance;
    return clamp(distance * cos_point / cos_texel, 0.5 * distance, 2.0 * distance);
}

void main() {
    int i = int(gl_GlobalInvocationID.x);
    int row = u_first_row + int(gl_GlobalInvocationID.y);  // this invocation's VPL
    if (i >= u_points_per_vpl) return;
    int vpl = int(ism_vpls[2 * row + 1].w);  // its atlas tile, which also picks its points
    int tri;
    vec2 bary;
    ism_surface_point(vpl, i, tri, bary);
    tri *= 3;
    vec3 v0 = ism_vertices[tri].xyz;
    vec3 e1 = ism_vertices[tri + 1].xyz - v0;
    vec3 e2 = ism_vertices[tri + 2].xyz - v0;
    vec3 world = v0 + bary.x * e1 + bary.y * e2;
    bool passed = ism_vertices[tri].w > 0.5;

    vec4 origin = ism_vpls[2 * row];
    vec3 n = ism_vpls[2 * row + 1].xyz;
    vec3 surface = cross(e1, e2);
    ivec2 tile = ivec2(vpl % u_columns, vpl / u_columns) * u_resolution;
    if (origin.w > 0.0) {  // directional: orthographic map, the point's depth over its square
        vec3 map;
        float depth;
        ism_project_directional(n, u_scene_centre, u_scene_radius, world, map, depth);
        float len_s = length(surface);
        float cos_surface = len_s > 0.0 ? abs(dot(surface, n)) / len_s : 0.0;
        int side = random_side(u_footprint_scale * sqrt(u_point_area * cos_surface)
                               * float(u_resolution) / (2.0 * u_scene_radius),
                               uint(vpl * u_points_per_vpl + i));
        ivec2 first = ivec2(floor(ism_texel(map, float(u_resolution)) - 0.5 * float(side)
                                  + 0.5));
        ivec2 lo = max(first, ivec2(0));
        ivec2 hi = min(first + side, ivec2(u_resolution));
        for (int y = lo.y; y < hi.y; ++y) {
            for (int x = lo.x; x < hi.x; ++x) {
                imageAtomicMin(u_splat, tile + ivec2(x, y),
                               floatBitsToUint(passed ? ISM_FAR : max(depth, 0.0)));
            }
        }
        return;
    }
    vec3 map;
    float distance;
    if (!ism_project(origin.xyz, n, world, map, distance)) return;
    vec3 d = (world - origin.xyz) / distance;
    float len_s = length(surface);
    if (!(len_s > 0.0)) return;
    // The point's disc (of u_footprint_scale² its share of the surface) projected into the
    // map: an ellipse c + M (a, b), a² + b² <= 1, M's columns the images of two radii. Grown
    // by half a texel (Σ = M Mᵀ + I / 4) so that edge-on discs still cover a line of texels.
    vec3 tu, tv;
    basis_of(surface / len_s, tu, tv);
    float radius = u_footprint_scale * sqrt(u_point_area / PI);
    float res = float(u_resolution);
    vec2 c = ism_texel(map, res);
    vec3 other;
    float ignored;
    vec2 cols[2];
    vec3 axes[2] = vec3[](tu, tv);
    for (int k = 0; k < 2; ++k) {
        cols[k] = ism_project(origin.xyz, n, world + radius * axes[k], other, ignored)
                  ? ism_texel(other, res) - c : vec2(0.0);
    }
    mat2 sigma = outerProduct(cols[0], cols[0]) + outerProduct(cols[1], cols[1]) + mat2(0.25);
    mat2 inverse_sigma = inverse(sigma);
    vec2 half_extent = min(sqrt(vec2(sigma[0][0], sigma[1][1])),
                           vec2(0.5 * float(u_max_footprint)));
    ivec2 lo = max(ivec2(floor(c - half_extent)), ivec2(0));
    ivec2 hi = min(ivec2(ceil(c + half_extent)), ivec2(u_resolution));
    vec3 t, b;
    basis_of(n, t, b);
    float texel_uv = 2.0 / res;
    for (int y = lo.y; y < hi.y; ++y) {
        for (int x = lo.x; x < hi.x; ++x) {
            vec2 offset = vec2(x, y) + 0.5 - c;
            if (dot(offset, inverse_sigma * offset) > 1.0) continue;
            vec2 uv = (vec2(x, y) + 0.5) * texel_uv - 1.0;
            float depth = passed ? ISM_FAR : plane_depth(t, b, n, uv, surface, d, distance);
            imageAtomicMin(u_splat, tile + ivec2(x, y), floatBitsToUint(depth));
        }
    }
}
