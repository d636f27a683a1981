// What one clear surface in front of the g-buffer's surface lets through to the camera:
// colour × (1 − F) at the view ray's angle, as rt_clear_transmittance dims a ray
// (raytrace_lib.glsl). Drawn with multiplicative blending over 1, so each pixel gets the
// product over every clear surface its camera ray crosses.
#include "fresnel_lib.glsl"

in vec3 v_world;
flat in vec3 v_normal;
flat in vec4 v_transmission;

uniform vec3 u_camera_position;
uniform vec3 u_camera_forward;
uniform bool u_orthographic;

layout(location = 0) out vec4 out_transmittance;

void main() {
    vec3 view = u_orthographic ? u_camera_forward : v_world - u_camera_position;
    float cos_i = abs(dot(v_normal, view)) / max(length(view), 1.0e-30);
    out_transmittance = vec4(clear_crossing(v_transmission.rgb, v_transmission.a, cos_i), 1.0);
}
