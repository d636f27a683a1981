// The scene's triangles as the ray tracer numbers them, for shaders that need a hit's surface:
// its position stream (x, y, z of 3 vertices per triangle) read as floats from a storage buffer
// (std430 pads vec3 arrays). Define SURFACE_VERTICES_BINDING before including.
#ifndef SURFACE_LIB_GLSL
#define SURFACE_LIB_GLSL

layout(std430, binding = SURFACE_VERTICES_BINDING) readonly buffer TriangleVertices {
    float triangle_positions[];
};

vec3 triangle_vertex(int triangle, int corner) {
    int i = 9 * triangle + 3 * corner;
    return vec3(triangle_positions[i], triangle_positions[i + 1], triangle_positions[i + 2]);
}

// The triangle's unit geometric normal, turned to face against ``dir`` (towards the ray's
// origin).
vec3 facing_normal(int triangle, vec3 dir) {
    vec3 a = triangle_vertex(triangle, 0);
    vec3 n = normalize(cross(triangle_vertex(triangle, 1) - a, triangle_vertex(triangle, 2) - a));
    return dot(n, dir) > 0.0 ? -n : n;
}
#endif
