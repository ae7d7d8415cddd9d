// Gouraud: the colour the vertices shaded, interpolated (and a textured object's diffuse
// term, per pixel).
centroid in vec3 v_colour;
out vec4 f_colour;
#ifdef VL_TEXTURED
centroid in vec2 v_uv;
centroid in vec3 v_irradiance;
#include "textured.glsl"
#endif
#include "cutout.glsl"
void main() {
#ifdef VL_CUTOUT
    cutout(v_uv);
#endif
#ifdef VL_TEXTURED
    f_colour = vec4(v_colour + textured_term(v_uv, v_irradiance), 1.0);
#else
    f_colour = vec4(v_colour, 1.0);
#endif
}
