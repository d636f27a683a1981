// Blender's Combined pass of one supersampled tile at pixel resolution (compose.py's pass
// algebra on the GPU, so that only pixels are read back): each pixel is the mean of its
// u_factor² supersamples' (direct + soft + indirect) × albedo + glossy + emission, alpha the
// surface's coverage; with BACKGROUND (a colour) or BACKGROUND_IMAGE (one per supersample)
// the uncovered part sees the background and alpha is 1. With HOLDOUTS a holdout's
// supersample (the g-buffer's geometric.w) is a hole: black, alpha 0, as in Cycles; with
// CATCHERS too, so are the supersamples of shadow catchers (the matte of
// frame/shadow_catcher.py). Defines: SOFT (blurred soft direct
// light), GLOSSY (each light's glossy radiance, added without the albedo), TRANSMITTANCE (what
// clear surfaces in front let through to the camera, per supersample: gpu/clear_view.py).

uniform sampler2D u_direct;
uniform sampler2D u_indirect;
#ifdef SOFT
uniform sampler2D u_soft;
#endif
#ifdef GLOSSY
uniform sampler2D u_direct_glossy;
uniform sampler2D u_indirect_glossy;
#ifdef SOFT
uniform sampler2D u_soft_glossy;
#endif
#endif
uniform sampler2D u_albedo;
uniform sampler2D u_emission;
uniform sampler2D u_normal;           // w: the supersample's coverage
#ifdef HOLDOUTS
uniform sampler2D u_geometric;        // w: -1 on a holdout
#endif
#if defined(BACKGROUND_IMAGE)
uniform sampler2D u_background;
#elif defined(BACKGROUND)
uniform vec3 u_background;
#endif
#ifdef TRANSMITTANCE
uniform sampler2D u_transmittance;
#endif
uniform int u_factor;                 // supersamples per pixel edge

layout(location = 0) out vec4 out_combined;

#ifdef CATCHERS
uniform isampler2D u_catchers;        // per triangle: 1 on a shadow catcher's (a table)

bool catcher(float code) {
    int triangle = int(code) - 1;
    if (triangle < 0) return false;
    int width = textureSize(u_catchers, 0).x;
    return texelFetch(u_catchers, ivec2(triangle % width, triangle / width), 0).r != 0;
}
#endif

bool holdout(ivec2 s) {
#ifdef HOLDOUTS
    float code = texelFetch(u_geometric, s, 0).w;
#ifdef CATCHERS
    if (catcher(code)) return true;
#endif
    return code < -0.5;
#else
    return false;
#endif
}

vec4 seen(ivec2 s) {
    if (holdout(s)) return vec4(0.0);
    vec4 light = texelFetch(u_direct, s, 0) + texelFetch(u_indirect, s, 0);
#ifdef SOFT
    light += texelFetch(u_soft, s, 0);
#endif
    vec4 c = light * texelFetch(u_albedo, s, 0) + texelFetch(u_emission, s, 0);
#ifdef GLOSSY
    c += texelFetch(u_direct_glossy, s, 0) + texelFetch(u_indirect_glossy, s, 0);
#ifdef SOFT
    c += texelFetch(u_soft_glossy, s, 0);
#endif
#endif
    float covered = texelFetch(u_normal, s, 0).w;
#if defined(BACKGROUND_IMAGE)
    return vec4(c.rgb + (1.0 - covered) * texelFetch(u_background, s, 0).rgb, 1.0);
#elif defined(BACKGROUND)
    return vec4(c.rgb + (1.0 - covered) * u_background, 1.0);
#else
    return vec4(c.rgb, covered);
#endif
}

vec4 supersample(ivec2 s) {
#ifdef TRANSMITTANCE
    vec3 through = texelFetch(u_transmittance, s, 0).rgb;
    vec4 c = seen(s) * vec4(through, 1.0);
#if !defined(BACKGROUND) && !defined(BACKGROUND_IMAGE)
    // a transparent film: clear surfaces in front of the background are as opaque as they
    // dim it (Cycles: alpha 1 - the mean of what they let through)
    if (!holdout(s)) {
        c.a += (1.0 - c.a) * (1.0 - (through.r + through.g + through.b) / 3.0);
    }
#endif
    return c;
#else
    return seen(s);
#endif
}

void main() {
    ivec2 pixel = ivec2(gl_FragCoord.xy);
    vec4 sum = vec4(0.0);
    for (int j = 0; j < u_factor; ++j)
        for (int i = 0; i < u_factor; ++i) sum += supersample(pixel * u_factor + ivec2(i, j));
    out_combined = sum / float(u_factor * u_factor);
}
