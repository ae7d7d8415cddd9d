// The reference display shaded at the vertices (Gouraud; its transform feedback gives
// vertex_colours): the vertex's grid read for its view direction, plus the emitters'
// highlights (the grid holds the rest: the solution minus them).
uniform mat4 mvp;
#include "clip.glsl"
uniform vec3 eye;
in vec3 in_position;
in vec3 in_normal;
in vec3 in_tangent;
centroid out vec3 v_colour;
#ifdef VL_TEXTURED
in vec2 in_uv;
in vec3 in_irradiance;
centroid out vec2 v_uv;
centroid out vec3 v_irradiance;
#endif
#include "lookup.glsl"
#include "emitters.glsl"
void main() {
    gl_Position = mvp * vec4(in_position, 1.0);
    VL_CLIP_VERTEX(in_position);
#ifdef VL_TEXTURED
    v_uv = in_uv;
    v_irradiance = in_irradiance;
#endif
    vec3 w = normalize(eye - in_position);
    v_colour = lookup(gl_VertexID, in_normal, in_tangent, w)
             + emitter_term(in_position, normalize(in_normal), w, ivec3(gl_VertexID), vec3(1.0, 0.0, 0.0));
}
