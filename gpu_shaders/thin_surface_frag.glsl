// Pixels where the geometry-aware blur cannot undo interleaving (frame/thin_surfaces.py). The
// blur (blur_frag.glsl, x then y) reaches pixel q from p through m = (p.x, q.y); on a surface
// thinner than the K×K pattern (a sunlit edge one pixel wide) the taps it finds hold few of
// the K² VPL subsets, so the few VPLs they hold light the pixel at K² times their weight.
// Two draws, like the blur's: ROWS writes, per pixel m, the columns mod K of the taps along
// its row whose blur weight from m is at least 1/2 (K bits, as a float); then the columns'
// draw gathers those of the taps m in p's column that weigh at least 1/2 from p, shifted by
// m's row mod K, and writes depth 1 where they hold under half of the K² (column, row)
// classes, which stand one to one for the subsets (interleave_lib.glsl), else 0 (background
// 0). K ≤ 4.

uniform sampler2D u_position;  // xyz world position, w view depth
uniform sampler2D u_normal;    // xyz shading normal, w 1 on surfaces
uniform int u_radius;
uniform int u_interleave;      // K
uniform float u_normal_power;
uniform float u_plane_tolerance;
#ifdef ROWS
layout(location = 0) out vec4 out_columns;
#else
uniform sampler2D u_columns;   // the ROWS draw's output
#endif

// Whether the blur weighs tap q at least 1/2 for centre p (never off the image or on the
// background).
bool weighty(vec4 position_p, vec3 normal_p, ivec2 q, ivec2 size) {
    if (any(lessThan(q, ivec2(0))) || any(greaterThanEqual(q, size))) return false;
    vec4 n_q = texelFetch(u_normal, q, 0);
    if (n_q.w == 0.0) return false;
    float plane = dot(texelFetch(u_position, q, 0).xyz - position_p.xyz, normal_p)
                  / max(abs(position_p.w) * u_plane_tolerance, 1e-30);
    return pow(max(dot(normal_p, n_q.xyz), 0.0), u_normal_power) * exp(-plane * plane) >= 0.5;
}

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    ivec2 size = textureSize(u_normal, 0);
    vec4 normal = texelFetch(u_normal, p, 0);
    vec4 position = texelFetch(u_position, p, 0);
    int k = u_interleave;
#ifdef ROWS
    uint columns = 0u;
    if (normal.w != 0.0) {
        for (int i = -u_radius; i <= u_radius; ++i) {
            ivec2 q = p + ivec2(i, 0);
            if (i == 0 || weighty(position, normal.xyz, q, size)) {
                columns |= 1u << uint(q.x & (k - 1));
            }
        }
    }
    out_columns = vec4(float(columns), 0.0, 0.0, 0.0);
#else
    gl_FragDepth = 0.0;
    if (normal.w == 0.0) return;
    uint classes = 0u;
    for (int j = -u_radius; j <= u_radius; ++j) {
        ivec2 m = p + ivec2(0, j);
        if (j == 0 || weighty(position, normal.xyz, m, size)) {
            classes |= uint(texelFetch(u_columns, m, 0).r) << uint(k * (m.y & (k - 1)));
        }
    }
    if (2 * bitCount(classes) < k * k) gl_FragDepth = 1.0;
#endif
}
