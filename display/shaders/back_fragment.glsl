// A triangle seen from behind: black. Surfaces are one-sided (the solver and the path
// tracer absorb light at a triangle's back), so a back shows no light but hides what is
// behind it. Drawn after every front face with a strict depth test, so that a front face
// at the same depth wins (a two-sided wall's back copy over the front copy's back). With
// VL_ATTRIBUTES (the renderer's attribute targets, for tests) it writes 0 to all six
// targets: no shaded surface, coverage 0. A masked object's back has its holes too
// (VL_CUTOUT).
#ifdef VL_CUTOUT
centroid in vec2 v_uv;
#endif
#include "cutout.glsl"
#ifdef VL_ATTRIBUTES
layout(location = 0) out vec4 f_position;
layout(location = 1) out vec4 f_normal;
layout(location = 2) out vec4 f_emitted;
layout(location = 3) out vec4 f_specular;
layout(location = 4) out vec4 f_bary;
layout(location = 5) out vec4 f_vertices;
void main() {
#ifdef VL_CUTOUT
    cutout(v_uv);
#endif
    f_position = vec4(0.0);
    f_normal = vec4(0.0);
    f_emitted = vec4(0.0);
    f_specular = vec4(0.0);
    f_bary = vec4(0.0);
    f_vertices = vec4(0.0);
}
#else
out vec4 f_colour;
void main() {
#ifdef VL_CUTOUT
    cutout(v_uv);
#endif
    f_colour = vec4(0.0, 0.0, 0.0, 1.0);
}
#endif
