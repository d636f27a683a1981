// Reflective shadow map texel: the surface point the light sees, its normal turned towards the
// light, and its albedo (the flux it receives is computed from the texel's solid angle or
// area on the CPU, addon/core/rsm.py). Drawn by shadow_vert.glsl with TRIANGLES; cutouts'
// texels are kept with probability their coverage (cutout_lib.glsl).
#include "cutout_lib.glsl"

in vec3 v_world;
flat in vec3 v_origin;
flat in int v_face;

layout(location = 0) out vec4 out_position;  // w = 1 where a surface was seen
layout(location = 1) out vec4 out_normal;
layout(location = 2) out vec4 out_albedo;

void main() {
    if (!cutout_kept()) discard;
    vec3 normal = normalize(cross(dFdx(v_world), dFdy(v_world)));
    vec3 towards_light = v_face >= 0 ? v_origin - v_world : -v_origin;
    if (dot(normal, towards_light) < 0.0) normal = -normal;
    out_position = vec4(v_world, 1.0);
    out_normal = vec4(normal, 0.0);
    out_albedo = vec4(material_of(v_triangle).albedo.rgb, 0.0);
}
