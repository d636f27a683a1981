// The Ambient Occlusion pass, as Cycles writes it: from each supersample's surface, rays in
// cosine-distributed directions about its shading normal, as long as the world's AO distance;
// the share that leaves unoccluded (one below the surface's geometric side counts as
// occluded). 0 where there is no surface, and on holdouts.
#include "raytrace_lib.glsl"
#include "hemisphere_lib.glsl"

in vec2 v_uv;

uniform sampler2D u_position;
uniform sampler2D u_normal;     // w = 1 on surfaces
uniform sampler2D u_geometric;  // facing the camera; w < 0 on holdouts
uniform float u_distance;
uniform float u_ray_offset;
uniform int u_rays;

layout(location = 0) out vec4 out_open;

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec4 normal = texelFetch(u_normal, px, 0);
    vec4 geometric = texelFetch(u_geometric, px, 0);
    out_open = vec4(0.0);
    if (normal.w == 0.0 || geometric.w < -0.5) return;
    vec3 origin = texelFetch(u_position, px, 0).xyz + geometric.xyz * u_ray_offset;
    float open = 0.0;
    for (int k = 0; k < u_rays; ++k) {
        vec3 dir = cosine_direction(normal.xyz, random2(uvec2(px), uint(k)));
        float t;
        int triangle;
        vec2 uv;
        vec3 unused = vec3(1.0);
        // a shadow ray's visibility: objects that cast no shadow let it through (Cycles'
        // opaque shadow ray)
        if (dot(geometric.xyz, dir) > 0.0
            && !rt_trace(origin, dir, 0.0, u_distance, RT_ANY | RT_SHADOW, t, triangle, uv,
                         unused)) {
            open += 1.0;
        }
    }
    out_open = vec4(vec3(open / float(u_rays)), 1.0);
}
