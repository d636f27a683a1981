// Writes the g-buffer. Normals are turned to face the camera (surfaces are two-sided, as in
// Cycles). With ONE_SIDED (visible light shapes) the back side is not drawn. With TEXTURED the
// albedo (capped to 1, as base colours are) and the emission come from image textures.
in vec3 v_world;
in vec3 v_normal;
in vec3 v_albedo;
in vec3 v_emission;

uniform vec3 u_camera_position;
uniform vec3 u_camera_forward;
uniform bool u_orthographic;
uniform mat4 u_view;

#ifdef TEXTURED
#include "textures_lib.glsl"
in vec2 v_uv;
flat in vec3 v_texture;
#endif

layout(location = 0) out vec4 out_position;  // xyz world, w = view-space depth (Blender's Z)
layout(location = 1) out vec4 out_normal;    // shading normal, w = 1 where there is a surface
layout(location = 2) out vec4 out_geometric; // geometric normal
layout(location = 3) out vec4 out_albedo;
layout(location = 4) out vec4 out_emission;

void main() {
    vec3 to_camera = u_orthographic ? -u_camera_forward : normalize(u_camera_position - v_world);
    vec3 geometric = normalize(cross(dFdx(v_world), dFdy(v_world)));
    if (dot(geometric, to_camera) < 0.0) geometric = -geometric;
    vec3 shading = normalize(v_normal);
#ifdef ONE_SIDED
    if (dot(shading, to_camera) <= 0.0) discard;
#endif
    if (dot(shading, to_camera) < 0.0) shading = -shading;
    float depth = -(u_view * vec4(v_world, 1.0)).z;
    out_position = vec4(v_world, depth);
    out_normal = vec4(shading, 1.0);
    out_geometric = vec4(geometric, 1.0);
    vec3 albedo = v_albedo;
    vec3 emission = v_emission;
#ifdef TEXTURED
    if (v_texture.x >= 0.0) albedo = clamp(texture_color(int(v_texture.x), v_uv), 0.0, 1.0);
    if (v_texture.y >= 0.0) {
        emission = max(v_texture.z * texture_color(int(v_texture.y), v_uv), 0.0);
    }
#endif
    out_albedo = vec4(albedo, 1.0);
    out_emission = vec4(emission, 1.0);
}
