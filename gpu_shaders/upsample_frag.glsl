// Geometry-aware upsampling of light gathered once per pixel to every supersample (a joint
// bilateral upsampling, Kopf et al. 2007): each supersample takes the 2×2 pixel samples around
// it, weighted bilinearly and by how well each lies on the supersample's surface, with the
// weights of the blur (blur_frag.glsl): the normals' similarity pow(max(n_s·n_p, 0),
// u_normal_power) and the distance of the pixel sample from the supersample's tangent plane
// relative to its view depth, exp(-(|(x_p - x_s)·n_s| / (depth_s · u_plane_tolerance))²).
// Where none of the four lies on the surface (a silhouette thinner than a pixel), the best
// match of the 4×4 pixels around it is taken whole. Background supersamples get 0. SOURCES
// light textures (default 1) are upsampled at once with the same weights. ADDED: each gets
// its u_added texture (light gathered per supersample) added.

#ifndef SOURCES
#define SOURCES 1
#endif

uniform sampler2D u_source[SOURCES];  // RGBA32F light, one sample per pixel
#ifdef ADDED
uniform sampler2D u_added[SOURCES];   // RGBA32F light, one sample per supersample
#endif
uniform sampler2D u_pixel_position;   // the pixel samples' g-buffer: xyz world, w view depth
uniform sampler2D u_pixel_normal;     //   xyz shading normal, w 1 on surfaces
uniform sampler2D u_position;         // the supersamples' g-buffer, the same layers
uniform sampler2D u_normal;
uniform int u_factor;                 // supersamples per pixel edge
uniform float u_normal_power;
uniform float u_plane_tolerance;

layout(location = 0) out vec4 out_light[SOURCES];

float match(vec4 position, vec3 normal, float plane_scale, ivec2 q) {
    vec4 n_q = texelFetch(u_pixel_normal, q, 0);
    if (n_q.w == 0.0) return 0.0;
    float plane = dot(texelFetch(u_pixel_position, q, 0).xyz - position.xyz, normal)
                  * plane_scale;
    return pow(max(dot(normal, n_q.xyz), 0.0), u_normal_power) * exp(-plane * plane);
}

vec4 added(int k, ivec2 s) {
#ifdef ADDED
    return texelFetch(u_added[k], s, 0);
#else
    return vec4(0.0);
#endif
}

void main() {
    ivec2 s = ivec2(gl_FragCoord.xy);
    for (int k = 0; k < SOURCES; ++k) out_light[k] = vec4(0.0);
    vec4 normal = texelFetch(u_normal, s, 0);
    if (normal.w == 0.0) return;
    vec4 position = texelFetch(u_position, s, 0);
    float plane_scale = 1.0 / max(abs(position.w) * u_plane_tolerance, 1e-30);
    ivec2 last = textureSize(u_pixel_normal, 0) - 1;
    vec2 at = (vec2(s) + 0.5) / float(u_factor) - 0.5;  // in pixel-sample coordinates
    ivec2 base = ivec2(floor(at));
    vec2 f = at - vec2(base);
    vec4 sum[SOURCES];
    for (int k = 0; k < SOURCES; ++k) sum[k] = vec4(0.0);
    float total = 0.0;
    for (int j = 0; j < 4; ++j) {
        ivec2 o = ivec2(j & 1, j >> 1);
        ivec2 q = clamp(base + o, ivec2(0), last);
        float bilinear = (o.x == 1 ? f.x : 1.0 - f.x) * (o.y == 1 ? f.y : 1.0 - f.y);
        float weight = bilinear * match(position, normal.xyz, plane_scale, q);
        for (int k = 0; k < SOURCES; ++k) sum[k] += weight * texelFetch(u_source[k], q, 0);
        total += weight;
    }
    if (total > 1e-3) {
        for (int k = 0; k < SOURCES; ++k) out_light[k] = sum[k] / total + added(k, s);
        return;
    }
    float best = 0.0;
    ivec2 chosen = clamp(base, ivec2(0), last);
    for (int j = 0; j < 16; ++j) {
        ivec2 q = clamp(base + ivec2(j & 3, j >> 2) - 1, ivec2(0), last);
        float weight = match(position, normal.xyz, plane_scale, q);
        if (weight > best) {
            best = weight;
            chosen = q;
        }
    }
    for (int k = 0; k < SOURCES; ++k) {
        out_light[k] = texelFetch(u_source[k], chosen, 0) + added(k, s);
    }
}
