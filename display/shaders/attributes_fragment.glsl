// What the per-pixel programs interpolate, for tests: each object through the program
// that draws it (rasterisation with and without a geometry shader may differ by an ulp),
// the vertex ids and barycentrics only through the geometry shader's (VL_TRIANGLE; -1
// and 0 without).
uniform int object_index;
#include "fitted_varyings.glsl"
#ifndef VL_TRIANGLE
const vec3 v_bary = vec3(0.0);
const ivec3 v_vertices = ivec3(-1);
#endif
layout(location = 0) out vec4 f_position;
layout(location = 1) out vec4 f_normal;
layout(location = 2) out vec4 f_emitted;
layout(location = 3) out vec4 f_specular;
layout(location = 4) out vec4 f_bary;
layout(location = 5) out vec4 f_vertices;
void main() {
    f_position = vec4(v_position, 1.0);
    f_normal = vec4(v_normal, 0.0);
    f_emitted = vec4(v_emitted, 0.0);
    f_specular = vec4(v_specular, 0.0);
    f_bary = vec4(v_bary, 0.0);
    f_vertices = vec4(vec3(v_vertices), float(object_index));
}
