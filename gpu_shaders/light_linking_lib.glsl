// Light linking (Blender's receiver collections, as Cycles renders them): a draw's light
// samples all come from emitters that light the same receiver sets, u_receivers (bits 0-31
// and 32-63, frame/gather.py); a surface is lit where the bit of its triangle's receiver set
// is (core/scene/model.py Instance.receiver_set), which the triangles' row texture holds
// beside each row (core/gpu/scene_buffers.py; 0 where it has no second component).
#ifndef LIGHT_LINKING_LIB_GLSL
#define LIGHT_LINKING_LIB_GLSL
#include "materials_lib.glsl"

uniform uvec2 u_receivers;

// Whether the draw's samples light ``triangle`` (any: no triangle, below 0).
bool lights_triangle(int triangle) {
    if (triangle < 0) return true;
    int width = textureSize(u_triangle_materials, 0).x;
    int set = texelFetch(u_triangle_materials, ivec2(triangle % width, triangle / width), 0).g;
    uint word = set < 32 ? u_receivers.x : u_receivers.y;
    return ((word >> uint(set & 31)) & 1u) != 0u;
}

#endif
