// Writes the g-buffer. The geometric normal is turned to face the camera (surfaces are
// two-sided, as in Cycles), and the shading normal turned with it where the camera sees the
// surface's back: its own side is not tested, since an interpolated normal seen at a grazing
// angle can face away from the camera on a front face (turning it then shaded the face from
// behind: black under a light in front). With ONE_SIDED (visible light shapes) the back side
// is not drawn. With TEXTURED the albedo (capped to 1, as base colours are) and the emission
// come from image textures, and a normal or bump map bends the shading normal. With GLOSSY
// (some material has a specular layer) the albedo is the diffuse layer's colour (Cycles'
// DiffCol) and three more layers hold the pixel's glossy lobe below any clear coat and sheen
// (principled_lib.glsl; the gather reads theirs from the material table); the
// glossy colour (Cycles' GlossCol) is (lobe_c.w, albedo.w, emission.w), as OpenGL
// guarantees only eight colour attachments; the geometric normal's w holds the triangle's
// index + 1 (-1 on a holdout) for the ID passes. With CUTOUTS (some
// material is there only in part) each supersample keeps a cutout's surface with probability
// its coverage (coverage_lib.glsl), in a pattern of each pass's own (u_cutout_seed), so
// supersamples and passes average it as Cycles' camera rays do.
#include "materials_lib.glsl"
#ifdef CUTOUTS
#include "coverage_lib.glsl"
uniform int u_cutout_seed;
#endif
#ifdef GLOSSY
#include "principled_lib.glsl"
#endif

in vec3 v_world;
in vec3 v_normal;
flat in int v_triangle;

uniform vec3 u_camera_position;
uniform vec3 u_camera_forward;
uniform bool u_orthographic;
uniform mat4 u_view;

#ifdef TEXTURED
#include "textures_lib.glsl"
in vec2 v_uv;
uniform float u_samples_per_pixel;  // across the screen: the g-buffer's supersamples

// v / |v|, or `otherwise` where v is zero, not finite or so long that squaring overflows (a
// normal map's texel of (0.5, 0.5, 0.5), NaN or infinite).
vec3 safe_unit(vec3 v, vec3 otherwise) {
    float squared = dot(v, v);
    return squared > 1.0e-20 && squared < 1.0e30 ? v * inversesqrt(squared) : otherwise;
}

// Cycles' Normal Map node in tangent space: the map's colour (2c - 1) in a frame whose tangent
// follows the UVs' u on the surface and whose bitangent is n x tangent, signed by v's direction
// (Blender's MikkTSpace tangents, here from the derivatives of position and UV), mixed with n
// by the strength (map: layer + 1, strength).
vec3 mapped_normal(vec3 n, vec4 map) {
    vec3 dp1 = dFdx(v_world), dp2 = dFdy(v_world);
    vec2 duv1 = dFdx(v_uv), duv2 = dFdy(v_uv);
    vec3 dp2perp = cross(dp2, n), dp1perp = cross(n, dp1);
    vec3 along_u = dp2perp * duv1.x + dp1perp * duv2.x;
    vec3 along_v = dp2perp * duv1.y + dp1perp * duv2.y;
    vec3 tangent = along_u - n * dot(n, along_u);
    if (!(dot(tangent, tangent) > 0.0)) return n;  // no UV gradient here: no frame
    tangent = normalize(tangent);
    vec3 bitangent = cross(n, tangent) * (dot(cross(n, tangent), along_v) < 0.0 ? -1.0 : 1.0);
    vec3 c = 2.0 * texture_color(int(map.x + 0.5) - 1, v_uv) - 1.0;
    vec3 mapped = safe_unit(c.x * tangent + c.y * bitangent + c.z * n, n);
    return map.y == 1.0 ? mapped : safe_unit(n + (mapped - n) * map.y, n);
}

float bump_height(int layer, vec2 uv) {
    return dot(texture_color(layer, uv), LUMINANCE);
}

// Cycles' Bump node (svm_node_set_bump): the height's differences over the filter width (in
// pixels: u_samples_per_pixel samples each) across the screen over the surface's (the
// screen-space surface gradient, Mikkelsen 2010), scaled by the distance (negative:
// inverted), mixed with n by the strength (map: layer + 1, strength, filter width, distance).
vec3 bumped_normal(vec3 n, vec4 map) {
    int layer = int(map.x + 0.5) - 1;
    float width = map.z * u_samples_per_pixel;
    vec3 dp_dx = dFdx(v_world) * width, dp_dy = dFdy(v_world) * width;
    float h = bump_height(layer, v_uv);
    float dh_dx = bump_height(layer, v_uv + dFdx(v_uv) * width) - h;
    float dh_dy = bump_height(layer, v_uv + dFdy(v_uv) * width) - h;
    vec3 rx = cross(dp_dy, n), ry = cross(n, dp_dx);
    float det = dot(dp_dx, rx);
    if (!(abs(det) > 0.0)) return n;  // no area between the supersamples: no gradient
    vec3 gradient = (dh_dx * rx + dh_dy * ry) / det;  // the height's, along the surface
    vec3 bumped = safe_unit(n - map.w * gradient, n);
    return map.y == 1.0 ? bumped : safe_unit(map.y * bumped + (1.0 - map.y) * n, n);
}
#endif

// The triangle's normal, from the position's screen derivatives; `interpolated` where they
// are below what float32 resolves this far from the origin (about 100 ulps: a view a few
// hundred thousandths of its distance from the origin wide, e.g. an orthographic scale of
// 1e-5 m) and so zero or of no direction.
vec3 geometric_normal(vec3 interpolated) {
    vec3 dx = dFdx(v_world), dy = dFdy(v_world);
    vec3 across = cross(dx, dy);
    float squared = dot(across, across);
    float resolvable = 1.0e-5 * length(v_world);
    return min(length(dx), length(dy)) > resolvable && squared > 0.0
        ? across * inversesqrt(squared) : interpolated;
}

layout(location = 0) out vec4 out_position;  // xyz world, w = view-space depth (Blender's Z)
layout(location = 1) out vec4 out_normal;    // shading normal, w = 1 where there is a surface
layout(location = 2) out vec4 out_geometric; // geometric normal
layout(location = 3) out vec4 out_albedo;
layout(location = 4) out vec4 out_emission;
#ifdef GLOSSY
layout(location = 5) out vec4 out_lobe_a;
layout(location = 6) out vec4 out_lobe_b;
layout(location = 7) out vec4 out_lobe_c;
#endif

void main() {
    Material material = material_of(v_triangle);
    if (material.albedo.w > 0.5) discard;  // an object the camera does not see (geometry.HIDDEN)
#ifdef CUTOUTS
    uint key = uint(v_triangle) + 2654435769u * uint(u_cutout_seed);
    if (!surface_kept(CUTOUT_COVERAGE(material.cutout, v_uv), uvec3(gl_FragCoord.xy, key))) {
        discard;
    }
#endif
    vec3 to_camera = u_orthographic ? -u_camera_forward : normalize(u_camera_position - v_world);
    vec3 shading = normalize(v_normal);
    vec3 geometric = geometric_normal(shading);
    if (dot(geometric, to_camera) < 0.0) geometric = -geometric;
#ifdef TEXTURED
    if (material.normal_map.x > 0.5) {
        shading = material.normal_map.z > 0.0 ? bumped_normal(shading, material.normal_map)
                                               : mapped_normal(shading, material.normal_map);
    }
#endif
#ifdef ONE_SIDED
    if (dot(shading, to_camera) <= 0.0) discard;
#endif
    if (dot(shading, geometric) < 0.0) shading = -shading;
    float depth = -(u_view * vec4(v_world, 1.0)).z;
    out_position = vec4(v_world, depth);
    out_normal = vec4(shading, 1.0);
    // w: the triangle's index + 1 (the ID passes: id_passes.py), -1 on a holdout
    // (geometry.HOLDOUT), 0 on a light's shape
#ifdef ONE_SIDED
    out_geometric = vec4(geometric, 0.0);
#else
    out_geometric = vec4(geometric, material.emission.w > 0.5 ? -1.0 : float(v_triangle + 1));
#endif
    vec3 albedo = material.albedo.rgb;
    vec3 emission = material.emission.rgb;
#ifdef TEXTURED
    vec3 layers = material.texture.xyz;
    if (layers.x >= 0.0) albedo = clamp(texture_color(int(layers.x), v_uv), 0.0, 1.0);
    if (layers.y >= 0.0) {
        emission = max(layers.z * texture_color(int(layers.y), v_uv), 0.0);
    }
#endif
    vec3 gloss = vec3(0.0);
#ifdef GLOSSY
    out_lobe_a = out_lobe_b = out_lobe_c = vec4(0.0);
    if (material.tint.w > 0.0) {
        vec3 below_layers;
        albedo *= principled_layers(albedo, material.specular, material.tint, material.coat,
                                    material.coat_tint, material.sheen,
                                    dot(shading, to_camera), gloss, out_lobe_a, out_lobe_b,
                                    out_lobe_c, below_layers);
        emission *= below_layers;  // Cycles dims emission under a clear coat and a sheen
        out_lobe_c.w = gloss.r;
    }
#endif
    out_albedo = vec4(albedo, gloss.g);
    out_emission = vec4(emission, gloss.b);
}
