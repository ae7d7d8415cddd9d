// Each fragment gets its triangle's three vertex ids, normals and tangents (flat) and its
// barycentrics: it reads the three vertices' grids with its own view direction.
#include "clip.glsl"
layout(triangles) in;
layout(triangle_strip, max_vertices = 3) out;
in vec3 g_position[];
in vec3 g_normal[];
in vec3 g_tangent[];
flat in int g_vertex[];
#ifdef VL_TEXTURED
in vec2 g_uv[];
in vec3 g_irradiance[];
centroid out vec2 f_uv;
centroid out vec3 f_irradiance;
#endif
centroid out vec3 f_position;
centroid out vec3 f_bary;
flat out ivec3 f_vertices;
flat out vec3 f_n0;
flat out vec3 f_n1;
flat out vec3 f_n2;
flat out vec3 f_t0;
flat out vec3 f_t1;
flat out vec3 f_t2;
void main() {
    for (int i = 0; i < 3; ++i) {
        gl_Position = gl_in[i].gl_Position;
        VL_CLIP_PASS(i);
        f_position = g_position[i];
        f_bary = vec3(i == 0, i == 1, i == 2);
#ifdef VL_TEXTURED
        f_uv = g_uv[i];
        f_irradiance = g_irradiance[i];
#endif
        f_vertices = ivec3(g_vertex[0], g_vertex[1], g_vertex[2]);
        f_n0 = g_normal[0]; f_n1 = g_normal[1]; f_n2 = g_normal[2];
        f_t0 = g_tangent[0]; f_t1 = g_tangent[1]; f_t2 = g_tangent[2];
        EmitVertex();
    }
    EndPrimitive();
}
