// The reference display shaded at the vertices (Gouraud; its transform feedback gives
// vertex_colours): the vertex's grid read for its view direction, plus the emitters'
// highlights (the grid holds the rest: the solution minus them).
uniform mat4 mvp;
uniform vec3 eye;
in vec3 in_position;
in vec3 in_normal;
in vec3 in_tangent;
centroid out vec3 v_colour;
#include "lookup.glsl"
#include "emitters.glsl"
void main() {
    gl_Position = mvp * vec4(in_position, 1.0);
    vec3 w = normalize(eye - in_position);
    v_colour = lookup(gl_VertexID, in_normal, in_tangent, w)
             + emitter_term(in_position, normalize(in_normal), w, ivec3(gl_VertexID), vec3(1.0, 0.0, 0.0));
}
