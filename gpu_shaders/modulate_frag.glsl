// The product of two textures texel by texel: light gathered at surface samples times the
// factor that carries it to the pixel (near_field.py's off-screen hits).
uniform sampler2D u_light;
uniform sampler2D u_factor;

layout(location = 0) out vec4 out_light;

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    out_light = vec4(texelFetch(u_light, p, 0).rgb * texelFetch(u_factor, p, 0).rgb, 0.0);
}
