// The fitted model's vertex stage without a geometry shader. With VL_GOURAUD: the colour
// alone, shaded at the vertex (Gouraud; its transform feedback gives vertex_colours);
// otherwise the attributes for the fragments, and the colour too where gouraud == 1.
uniform mat4 mvp;
#include "clip.glsl"
uniform vec3 eye;
#include "fitted_attributes.glsl"
#ifndef VL_GOURAUD
uniform int gouraud;
#define VL_OUT
#include "fitted_varyings.glsl"
#endif
centroid out vec3 v_colour;
#if defined(VL_GOURAUD) && defined(VL_TEXTURED)
centroid out vec2 v_uv;
centroid out vec3 v_irradiance;
#endif
#include "shade.glsl"
vec3 shade_vertex() {   // a vertex's weights: its own id, (1, 0, 0)
    return shade(normalize(in_normal), in_position, normalize(eye - in_position), in_emitted, in_specular, in_probe,
                 ivec3(gl_VertexID), vec3(1.0, 0.0, 0.0));
}
void main() {
    gl_Position = mvp * vec4(in_position, 1.0);
    VL_CLIP_VERTEX(in_position);
#ifdef VL_TEXTURED
    v_uv = in_uv;
    v_irradiance = in_irradiance;
#endif
#ifdef VL_GOURAUD
    v_colour = shade_vertex();
#else
    v_position = in_position;
    v_normal = in_normal;
    v_emitted = in_emitted;
    v_specular = in_specular;
    v_probe = in_probe;
    v_colour = gouraud == 1 ? shade_vertex() : vec3(0.0);
#endif
}
