// Shadow-map rendering: every atlas tile (a cube face or a directional map) in one instanced
// draw. Instance i reads its tile from the tile table, projects the vertex for that tile and
// places the result in the tile's rectangle of the atlas; clip distances cut it to the tile.
#include "common_lib.glsl"

in vec3 in_position;

uniform sampler2D u_tiles;     // 2 texels per tile: (origin or axis, face), (near, far, col, row)
uniform vec2 u_atlas_tiles;    // columns, rows of the atlas
uniform vec3 u_scene_centre;
uniform float u_scene_radius;

out vec3 v_world;
flat out vec3 v_origin;
flat out int v_face;

void main() {
    vec4 t0 = texelFetch(u_tiles, ivec2(0, gl_InstanceID), 0);
    vec4 t1 = texelFetch(u_tiles, ivec2(1, gl_InstanceID), 0);
    int face = int(t0.w);
    vec4 clip = face >= 0 ? cube_face_clip(in_position, t0.xyz, face, t1.x, t1.y)
                          : directional_clip(in_position, t0.xyz, u_scene_centre,
                                             u_scene_radius);
    gl_ClipDistance[0] = clip.w + clip.x;
    gl_ClipDistance[1] = clip.w - clip.x;
    gl_ClipDistance[2] = clip.w + clip.y;
    gl_ClipDistance[3] = clip.w - clip.y;
    vec2 scale = 1.0 / u_atlas_tiles;
    vec2 centre = (2.0 * t1.zw + 1.0) * scale - 1.0;
    gl_Position = vec4(clip.xy * scale + centre * clip.w, clip.z, clip.w);
    v_world = in_position;
    v_origin = t0.xyz;
    v_face = face;
}
