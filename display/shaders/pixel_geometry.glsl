// Per pixel with per-vertex texture values (per-light coefficients, the emitters'
// visibility): each fragment gets its triangle's three vertex ids (flat) and its
// barycentrics (interpolated like any varying), and blends the three vertices' values.
#include "clip.glsl"
layout(triangles) in;
layout(triangle_strip, max_vertices = 3) out;
in vec3 g_position[];
in vec3 g_normal[];
in vec3 g_emitted[];
in vec3 g_specular[];
in vec3 g_probe[];
flat in int g_vertex[];
#ifdef VL_TEXTURED
in vec2 g_uv[];
in vec3 g_irradiance[];
#endif
#define VL_OUT
#include "fitted_varyings.glsl"
void main() {
    for (int i = 0; i < 3; ++i) {
        gl_Position = gl_in[i].gl_Position;
        VL_CLIP_PASS(i);
        v_position = g_position[i];
        v_normal = g_normal[i];
        v_emitted = g_emitted[i];
        v_specular = g_specular[i];
        v_probe = g_probe[i];
#ifdef VL_TEXTURED
        v_uv = g_uv[i];
        v_irradiance = g_irradiance[i];
#endif
        v_bary = vec3(i == 0, i == 1, i == 2);
        v_vertices = ivec3(g_vertex[0], g_vertex[1], g_vertex[2]);
        EmitVertex();
    }
    EndPrimitive();
}
