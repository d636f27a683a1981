// Image textures packed by core/gpu/texture_array.py: each image in a rectangle of its own in
// the pages of one RGBA32UI array texture, a texel as four float32 bit patterns or, for an
// 8-bit image, four texels in one (RGBA8 each, texel x in word x % 4 of texel x / 4); a table
// holds per texture (width, height, sRGB flag, mode) in row 0 and its rectangle's (x, y,
// page, 1 for 8-bit) in row 1, mode = interpolation (0 Closest, 1 Linear, 2 Cubic) + 4 ×
// extension (0 Repeat, 1 Extend, 2 Clip, 3 Mirror). Sampled as Cycles samples (the CPU twin is textures.sample): values
// interpolated as stored, then colour decoded from sRGB (alpha is linear). texture_color
// samples the g-buffer's arrays (u_textures, u_texture_sizes); texture_sample any pair.
#ifndef TEXTURES_LIB_GLSL
#define TEXTURES_LIB_GLSL

uniform usampler2DArray u_textures;
uniform sampler2D u_texture_sizes;

const vec3 LUMINANCE = vec3(0.2126, 0.7152, 0.0722);  // a colour as a float (Rec. 709)

const int EXTENSION_REPEAT = 0;
const int EXTENSION_EXTEND = 1;
const int EXTENSION_CLIP = 2;
const int EXTENSION_MIRROR = 3;

vec3 srgb_to_linear(vec3 c) {
    return mix(c / 12.92, pow((max(c, 0.04045) + 0.055) / 1.055, vec3(2.4)),
               step(vec3(0.04045), c));
}

// A texel coordinate (float) brought to a small integer with the same taps: Repeat and
// Mirror reduced by their period, Extend and Clip clamped a few texels outside the image.
int texture_base(float p, float size, int extension) {
    if (extension == EXTENSION_REPEAT) return int(p - size * floor(p / size));
    if (extension == EXTENSION_MIRROR) return int(p - 2.0 * size * floor(p / (2.0 * size)));
    return int(clamp(p, -4.0, size + 3.0));
}

// Tap index i (>= -5) inside [0, size) for the extension; -1 for Clip outside the image.
int texture_wrap(int i, int size, int extension) {
    if (extension == EXTENSION_REPEAT) return (i + 8 * size) % size;
    if (extension == EXTENSION_MIRROR) {
        int m = (i + 8 * size) % (2 * size);
        return m < size ? m : 2 * size - 1 - m;
    }
    if (extension == EXTENSION_EXTEND) return clamp(i, 0, size - 1);
    return (i < 0 || i >= size) ? -1 : i;
}

vec4 cubic_weights(float t) {
    float s = 1.0 - t;
    return vec4(s * s * s, 3.0 * t * t * t - 6.0 * t * t + 4.0,
                3.0 * s * s * s - 6.0 * s * s + 4.0, t * t * t) / 6.0;
}

// Texel (x, y) of the texture at ``origin`` (``bytes``: an 8-bit image, four texels a word).
vec4 texel_at(usampler2DArray textures, ivec3 origin, bool bytes, int x, int y) {
    if (bytes) {
        uvec4 words = texelFetch(textures, origin + ivec3(x / 4, y, 0), 0);
        return unpackUnorm4x8(words[x % 4]);
    }
    return uintBitsToFloat(texelFetch(textures, origin + ivec3(x, y, 0), 0));
}

// Decoded colour and alpha of texture ``layer`` at uv.
vec4 texture_sample(usampler2DArray textures, sampler2D sizes, int layer, vec2 uv) {
    vec4 info = texelFetch(sizes, ivec2(layer, 0), 0);
    vec4 place = texelFetch(sizes, ivec2(layer, 1), 0);
    ivec3 origin = ivec3(place.xyz);
    bool bytes = place.w > 0.5;
    ivec2 size = ivec2(info.xy);
    int mode = int(info.w + 0.5);
    int interpolation = mode % 4;
    int extension = mode / 4;
    vec2 p = uv * info.xy;
    int taps = 1;
    vec4 wx = vec4(1.0, 0.0, 0.0, 0.0);
    vec4 wy = wx;
    ivec2 first;
    if (interpolation == 0) {
        p = floor(p);
    } else {
        p -= 0.5;  // texel centres at half-integers
        vec2 f = p - floor(p);
        p = floor(p);
        if (interpolation == 1) {
            taps = 2;
            wx.xy = vec2(1.0 - f.x, f.x);
            wy.xy = vec2(1.0 - f.y, f.y);
        } else {
            taps = 4;
            wx = cubic_weights(f.x);
            wy = cubic_weights(f.y);
            p -= 1.0;
        }
    }
    first = ivec2(texture_base(p.x, info.x, extension), texture_base(p.y, info.y, extension));
    vec4 c = vec4(0.0);
    for (int b = 0; b < taps; ++b) {
        int y = texture_wrap(first.y + b, size.y, extension);
        for (int a = 0; a < taps; ++a) {
            int x = texture_wrap(first.x + a, size.x, extension);
            if (x >= 0 && y >= 0) {
                c += wx[a] * wy[b] * texel_at(textures, origin, bytes, x, y);
            }
        }
    }
    return info.z > 0.5 ? vec4(srgb_to_linear(c.rgb), c.a) : c;
}

vec3 texture_color(int layer, vec2 uv) {
    return texture_sample(u_textures, u_texture_sizes, layer, uv).rgb;
}

#endif
