// The material table of core/geometry.py and each triangle's row in it, as textures
// (core/scene_buffers.py; OpenGL 4.1 has no storage buffers): entry i of a table is texel
// (i % width, i / width). A material row is eleven texels: albedo, emission, texture attribute,
// the specular parameters (roughness, metallic, eta, s_avg), (F0 x tint, glossy flag), the
// clear coat (weight, roughness, eta, the diffuse roughness: core/scene/oren_nayar.py) and
// its tint (rgb, whether the sheen is layered), the sheen (weight x tint, roughness)
// (core/scene/principled.py's specular_row), the cutout (coverage_lib.glsl), the normal map
// (gbuffer_frag.glsl) and the translucency (rgb: the share of the diffuse light let through
// to the other side; gather_frag.glsl).
// Vertex shaders pass the triangle index (gl_VertexID / 3, which instanced draws do not reset).
#ifndef MATERIALS_LIB_GLSL
#define MATERIALS_LIB_GLSL

uniform isampler2D u_triangle_materials;
uniform sampler2D u_materials;

struct Material {
    vec4 albedo;
    vec4 emission;
    vec4 texture;  // albedo layer, emission layer (-1 = none), emission strength
    vec4 specular;
    vec4 tint;
    vec4 coat;
    vec4 coat_tint;
    vec4 sheen;
    vec4 cutout;
    vec4 normal_map;  // layer + 1 (0: none), strength, a bump map's filter width, its distance
    vec4 translucency;
};

const int MATERIAL_TEXELS = 11;  // a row's texels (core/scene/geometry.py's MATERIAL_COLUMNS / 4)

vec4 material_texel(int i) {
    int width = textureSize(u_materials, 0).x;
    return texelFetch(u_materials, ivec2(i % width, i / width), 0);
}

// The first texel of a triangle's material row.
int material_row(int triangle) {
    int width = textureSize(u_triangle_materials, 0).x;
    int row = texelFetch(u_triangle_materials, ivec2(triangle % width, triangle / width), 0).r;
    return MATERIAL_TEXELS * row;
}

Material material_of(int triangle) {
    int first = material_row(triangle);
    return Material(material_texel(first), material_texel(first + 1),
                    material_texel(first + 2), material_texel(first + 3),
                    material_texel(first + 4), material_texel(first + 5),
                    material_texel(first + 6), material_texel(first + 7),
                    material_texel(first + 8), material_texel(first + 9),
                    material_texel(first + 10));
}

// The share of the diffuse light a triangle lets through to its other side (Translucent BSDF).
vec3 translucency_of(int triangle) {
    return material_texel(material_row(triangle) + 10).rgb;
}

#endif
