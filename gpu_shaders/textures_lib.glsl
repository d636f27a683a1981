// Image textures packed by core/textures.py: one layer per image, the image in the layer's
// lower-left corner; u_texture_sizes holds (width, height, sRGB flag) per layer. Bilinear
// between texel centres with Repeat extension, decoded from sRGB after interpolation (Cycles).
#ifndef TEXTURES_LIB_GLSL
#define TEXTURES_LIB_GLSL

uniform sampler2DArray u_textures;
uniform sampler2D u_texture_sizes;

vec3 srgb_to_linear(vec3 c) {
    return mix(c / 12.92, pow((max(c, 0.04045) + 0.055) / 1.055, vec3(2.4)),
               step(vec3(0.04045), c));
}

vec3 texture_color(int layer, vec2 uv) {
    vec4 info = texelFetch(u_texture_sizes, ivec2(layer, 0), 0);
    ivec2 size = ivec2(info.xy);
    vec2 p = uv * info.xy - 0.5;
    vec2 base = floor(p);
    vec2 f = p - base;
    ivec2 i0 = min(ivec2(mod(base, info.xy)), size - 1);
    ivec2 i1 = (i0 + 1) % size;
    vec3 c00 = texelFetch(u_textures, ivec3(i0.x, i0.y, layer), 0).rgb;
    vec3 c10 = texelFetch(u_textures, ivec3(i1.x, i0.y, layer), 0).rgb;
    vec3 c01 = texelFetch(u_textures, ivec3(i0.x, i1.y, layer), 0).rgb;
    vec3 c11 = texelFetch(u_textures, ivec3(i1.x, i1.y, layer), 0).rgb;
    vec3 c = mix(mix(c00, c10, f.x), mix(c01, c11, f.x), f.y);
    return info.z > 0.5 ? srgb_to_linear(c) : c;
}

#endif
