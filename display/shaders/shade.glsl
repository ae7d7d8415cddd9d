// fit.npz's shading formula (version 3): emitted + lights + probe + the emitters' highlights.
// Each part compiles to nothing under #define VL_NO_LIGHTS / VL_NO_PROBE / VL_NO_EMITTERS
// (programs for objects and modes without it: Mesa's llvmpipe pays for the code of a
// shader even where a uniform skips it, measured 6-8 times a diffuse frame's time).
#include "lights.glsl"
#include "probe.glsl"
#include "emitters.glsl"
vec3 shade(vec3 n, vec3 x, vec3 w, vec3 emitted, vec3 specular, vec3 probe_weight, ivec3 vertices, vec3 weights) {
    return lights_shade(n, x, w, emitted, specular, vertices, weights) + probe_term(x, n, w, probe_weight)
         + emitter_term(x, n, w, vertices, weights);
}
