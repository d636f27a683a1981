// Instanced rendering into an atlas of tiles: instance i reads its tile from the tile table
// (cube face of a light, or a directional map), projects a vertex for that tile, places it in
// the tile's rectangle of the atlas and sets clip distances that cut it to the tile.
#ifndef TILES_LIB_GLSL
#define TILES_LIB_GLSL
#include "common_lib.glsl"

uniform sampler2D u_tiles;     // 2 texels per tile: (origin or axis, face), (near, far, col, row)
uniform vec2 u_atlas_tiles;    // columns, rows of the atlas
uniform vec3 u_scene_centre;
uniform float u_scene_radius;

vec4 atlas_tile_position(vec3 world, int tile, out vec3 origin, out int face) {
    vec4 t0 = texelFetch(u_tiles, ivec2(0, tile), 0);
    vec4 t1 = texelFetch(u_tiles, ivec2(1, tile), 0);
    origin = t0.xyz;
    face = int(t0.w);
    vec4 clip = face >= 0 ? cube_face_clip(world, origin, face, t1.x, t1.y)
                          : directional_clip(world, origin, u_scene_centre, u_scene_radius);
    gl_ClipDistance[0] = clip.w + clip.x;
    gl_ClipDistance[1] = clip.w - clip.x;
    gl_ClipDistance[2] = clip.w + clip.y;
    gl_ClipDistance[3] = clip.w - clip.y;
    vec2 scale = 1.0 / u_atlas_tiles;
    vec2 centre = (2.0 * t1.zw + 1.0) * scale - 1.0;
    return vec4(clip.xy * scale + centre * clip.w, clip.z, clip.w);
}
#endif
