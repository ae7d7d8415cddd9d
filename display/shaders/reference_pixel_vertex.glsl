// The reference display per pixel (with reference_pixel_geometry.glsl): the attributes
// and the vertex's id, handed on.
uniform mat4 mvp;
#include "clip.glsl"
in vec3 in_position;
in vec3 in_normal;
in vec3 in_tangent;
out vec3 g_position;
out vec3 g_normal;
out vec3 g_tangent;
flat out int g_vertex;
#ifdef VL_TEXTURED
in vec2 in_uv;
in vec3 in_irradiance;
out vec2 g_uv;
out vec3 g_irradiance;
#endif
void main() {
    gl_Position = mvp * vec4(in_position, 1.0);
    VL_CLIP_VERTEX(in_position);
    g_position = in_position;
    g_normal = in_normal;
    g_tangent = in_tangent;
    g_vertex = gl_VertexID;
#ifdef VL_TEXTURED
    g_uv = in_uv;
    g_irradiance = in_irradiance;
#endif
}
