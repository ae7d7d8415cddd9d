// The fitted model per pixel with a geometry shader (pixel_geometry.glsl): the attributes
// and the vertex's id, handed on as they are.
uniform mat4 mvp;
#include "clip.glsl"
#include "fitted_attributes.glsl"
out vec3 g_position;
out vec3 g_normal;
out vec3 g_emitted;
out vec3 g_specular;
out vec3 g_probe;
flat out int g_vertex;
#ifdef VL_TEXTURED
out vec2 g_uv;
out vec3 g_irradiance;
#endif
void main() {
    gl_Position = mvp * vec4(in_position, 1.0);
    VL_CLIP_VERTEX(in_position);
    g_position = in_position;
    g_normal = in_normal;
    g_emitted = in_emitted;
    g_specular = in_specular;
    g_probe = in_probe;
    g_vertex = gl_VertexID;
#ifdef VL_TEXTURED
    g_uv = in_uv;
    g_irradiance = in_irradiance;
#endif
}
