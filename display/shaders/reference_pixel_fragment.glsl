// The three vertices' grids read with the fragment's view direction and blended by its
// barycentrics, plus the emitters' highlights at the pixel.
uniform vec3 eye;
centroid in vec3 f_position;
centroid in vec3 f_bary;
flat in ivec3 f_vertices;
flat in vec3 f_n0;
flat in vec3 f_n1;
flat in vec3 f_n2;
flat in vec3 f_t0;
flat in vec3 f_t1;
flat in vec3 f_t2;
out vec4 f_colour;
#ifdef VL_TEXTURED
centroid in vec2 f_uv;
centroid in vec3 f_irradiance;
#include "textured.glsl"
#endif
#include "lookup.glsl"
#include "emitters.glsl"
#include "cutout.glsl"
void main() {
#ifdef VL_CUTOUT
    cutout(f_uv);
#endif
    vec3 w = normalize(eye - f_position);
    vec3 c = f_bary.x * lookup(f_vertices.x, f_n0, f_t0, w)
           + f_bary.y * lookup(f_vertices.y, f_n1, f_t1, w)
           + f_bary.z * lookup(f_vertices.z, f_n2, f_t2, w);
    // the emitters' highlights at the pixel (the grid holds the rest: the solution minus them)
    vec3 n = normalize(f_bary.x * f_n0 + f_bary.y * f_n1 + f_bary.z * f_n2);
    c += emitter_term(f_position, n, w, f_vertices, f_bary);
#ifdef VL_TEXTURED
    c += textured_term(f_uv, f_irradiance);
#endif
    f_colour = vec4(c, 1.0);
}
