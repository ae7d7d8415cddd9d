// The fitted model's fragment stage: the shading formula at the pixel (or, where
// gouraud == 1, the colour the vertices shaded). With VL_TRIANGLE (the geometry shader's
// program, and the web page) the triangle's vertex ids and barycentrics blend the
// per-vertex texture values; without, no object drawn by it has any.
uniform vec3 eye;
uniform vec4 flat_colour;   // w > 0: draw this colour instead (object masks)
#include "fitted_varyings.glsl"
#ifndef VL_TRIANGLE
uniform int gouraud;
centroid in vec3 v_colour;
const ivec3 v_vertices = ivec3(0);
const vec3 v_bary = vec3(1.0, 0.0, 0.0);
#endif
out vec4 f_colour;
#include "shade.glsl"
#include "textured.glsl"
vec3 shade_fragment() {
    return shade(normalize(v_normal), v_position, normalize(eye - v_position), v_emitted, v_specular, v_probe,
                 v_vertices, v_bary);
}
#include "cutout.glsl"
void main() {
#ifdef VL_CUTOUT
    cutout(v_uv);
#endif
#ifdef VL_TRIANGLE
    vec3 c = shade_fragment();
#else
    vec3 c = gouraud == 1 ? v_colour : shade_fragment();
#endif
#ifdef VL_TEXTURED
    c += textured_term(v_uv, v_irradiance);
#endif
    f_colour = flat_colour.w > 0.0 ? vec4(flat_colour.rgb, 1.0) : vec4(c, 1.0);
}
