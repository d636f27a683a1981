// Which texel an invocation of an imperfect-shadow-map image pass (pull, push) handles. With
// ISM_TILE_LIST (a partial update) z picks an entry of the list of tiles to update and x, y the
// texel within that tile, so the work scales with the tiles updated; else x, y is the texel of
// the whole atlas level. ivec2(-1) for invocations outside.
#ifndef ISM_TILE_LIST_LIB
#define ISM_TILE_LIST_LIB

#ifdef ISM_TILE_LIST
layout(std430, binding = ISM_TILE_LIST) readonly buffer IsmTileList { int ism_tile_list[]; };
#endif

ivec2 ism_pass_texel(int resolution, ivec2 size) {
#ifdef ISM_TILE_LIST
    ivec2 local = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(local, ivec2(resolution)))) return ivec2(-1);
    int tile = ism_tile_list[gl_GlobalInvocationID.z];
    int columns = size.x / resolution;
    return ivec2(tile % columns, tile / columns) * resolution + local;
#else
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    return any(greaterThanEqual(p, size)) ? ivec2(-1) : p;
#endif
}

#endif
