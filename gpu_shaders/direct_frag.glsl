// Direct light of one batch of light samples, added (blending) to the DiffDir accumulator in
// Blender's pass unit: irradiance / pi (the pass times DiffCol is the diffuse radiance).
#include "lights_lib.glsl"

in vec2 v_uv;

uniform sampler2D u_position;
uniform sampler2D u_normal;
uniform sampler2D u_geometric;
uniform int u_first;
uniform int u_count;

out vec4 out_light;

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec4 normal = texelFetch(u_normal, px, 0);
    if (normal.w == 0.0) discard;
    vec3 world = texelFetch(u_position, px, 0).xyz;
    vec3 geometric = texelFetch(u_geometric, px, 0).xyz;
    vec3 irradiance = vec3(0.0);
    for (int i = 0; i < u_count; ++i) {
        irradiance += sample_irradiance(light_sample(u_first + i), world, normal.xyz, geometric);
    }
    out_light = vec4(irradiance / PI, 0.0);
}
