// Shared definitions: light-sample kinds, the light-sample table layout, and the shadow-map
// projections used both to render shadow maps and to look them up (one code path, so the two
// can never disagree).
#ifndef COMMON_LIB_GLSL
#define COMMON_LIB_GLSL

#define PI 3.14159265358979

// Light-sample kinds (see addon/core/lights.py).
#define KIND_OMNI 0        // point light: intensity the same in every direction
#define KIND_COSINE 1      // one-sided cosine emitter (area-light sample, sphere-light sample)
#define KIND_COSINE2 2     // two-sided cosine emitter (emissive-surface sample)
#define KIND_DIRECTIONAL 3 // sun or world direction: irradiance, no falloff

// Rotations taking cube face f's viewing direction (+X, -X, +Y, -Y, +Z, -Z) to -Z.
// Rows are the face camera's right, up and backward axes.
const mat3 CUBE_FACE_ROTATION[6] = mat3[6](
    transpose(mat3(vec3(0, 0, -1), vec3(0, -1, 0), vec3(-1, 0, 0))),
    transpose(mat3(vec3(0, 0, 1), vec3(0, -1, 0), vec3(1, 0, 0))),
    transpose(mat3(vec3(1, 0, 0), vec3(0, 0, 1), vec3(0, -1, 0))),
    transpose(mat3(vec3(1, 0, 0), vec3(0, 0, -1), vec3(0, 1, 0))),
    transpose(mat3(vec3(1, 0, 0), vec3(0, -1, 0), vec3(0, 0, -1))),
    transpose(mat3(vec3(-1, 0, 0), vec3(0, -1, 0), vec3(0, 0, 1))));

int cube_face_of(vec3 v) {
    vec3 a = abs(v);
    if (a.x >= a.y && a.x >= a.z) return v.x >= 0.0 ? 0 : 1;
    if (a.y >= a.z) return v.y >= 0.0 ? 2 : 3;
    return v.z >= 0.0 ? 4 : 5;
}

// An orthonormal basis around a unit axis (Duff et al. 2017), for directional shadow maps.
void basis_of(vec3 n, out vec3 t, out vec3 b) {
    float s = n.z >= 0.0 ? 1.0 : -1.0;
    float a = -1.0 / (s + n.z);
    float c = n.x * n.y * a;
    t = vec3(1.0 + s * n.x * n.x * a, s * c, -s * n.x);
    b = vec3(c, s + n.y * n.y * a, -n.y);
}

// Clip-space position of a world point in cube face `face` of a light at `origin`.
vec4 cube_face_clip(vec3 world, vec3 origin, int face, float near, float far) {
    vec3 local = CUBE_FACE_ROTATION[face] * (world - origin);
    float z = (-(far + near) * local.z - 2.0 * far * near) / (far - near);
    return vec4(local.x, local.y, z, -local.z);
}

// Directional (orthographic) map over the scene's bounding sphere (centre, radius), looking
// along `axis`. Returns clip position; depth along the axis is measured from the sphere's front.
vec4 directional_clip(vec3 world, vec3 axis, vec3 centre, float radius) {
    vec3 t, b;
    basis_of(axis, t, b);
    vec3 d = world - centre;
    float depth = dot(d, axis) + radius;
    return vec4(dot(d, t) / radius, dot(d, b) / radius, depth / radius - 1.0, 1.0);
}

float directional_depth(vec3 world, vec3 axis, vec3 centre, float radius) {
    return dot(world - centre, axis) + radius;
}
// PCG hash (Jarzynski & Olano 2020): 32 well-mixed bits of v.
uint pcg(uint v) {
    uint state = v * 747796405u + 2891336453u;
    uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

#endif
