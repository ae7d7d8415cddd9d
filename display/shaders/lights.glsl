// The virtual lights of fit.npz's shading formula (fitting.model.FittedObject.shade).
#include "store.glsl"
#ifdef VL_NO_LIGHTS
vec3 lights_shade(vec3 n, vec3 x, vec3 w, vec3 emitted, vec3 specular, ivec3 vertices, vec3 weights) { return emitted; }
#else
uniform int n_lights;          // lights drawn: the object's first n_lights (--lights)
uniform int light_stride;      // the object's K: per-light coefficients per vertex
uniform int per_light;         // 1: light k's coefficient of vertex v is value coefficient_base + v * K + k
uniform sampler2D lights;      // row k: (light_pos xyzw as GL_POSITION), (rgb, shininess)
#ifdef VL_STORE_PAGES
uniform ivec2 coefficient_base;  // an address in the renderer's float store (store.glsl)
#else
uniform int coefficient_base;    // the page: a texture VL_TEXTURE_WIDTH wide, value i at texel (i % width, i / width)
uniform sampler2D coefficients;
const int COEFFICIENT_WIDTH = VL_TEXTURE_WIDTH;
#endif
const float NEGLIGIBLE = 30.0;  // fitting.lobes.NEGLIGIBLE: the lobe is 0 where (1 - c) p > 30
vec3 coefficient_at(int vertex, int k) {
#ifdef VL_STORE_PAGES
    return store_value(coefficient_base, vertex, light_stride, k).rgb;
#else
    int i = coefficient_base + vertex * light_stride + k;
    return texelFetch(coefficients, ivec2(i % COEFFICIENT_WIDTH, i / COEFFICIENT_WIDTH), 0).rgb;
#endif
}
// light k's lobe times its colour at point x, unit normal n, unit w towards the eye
vec3 light_term(int k, vec3 n, vec3 x, vec3 w) {
    vec4 p = texelFetch(lights, ivec2(0, k), 0);
    vec4 rgb_p = texelFetch(lights, ivec2(1, k), 0);
    vec3 l = p.xyz - p.w * x;      // l_k(x) = normalize(xyz - w x)
    float l_len = length(l);
    if (!(l_len > 0.0)) return vec3(0.0);   // a point light at x: no light
    vec3 h = l / l_len + w;
    float h_len = length(h);
    if (!(h_len > 0.0)) return vec3(0.0);
    float c = dot(n, h) / h_len;
    if (!(c > 0.0) || (1.0 - c) * rgb_p.a > NEGLIGIBLE) return vec3(0.0);
    return pow(c, rgb_p.a) * rgb_p.rgb;
}
// emitted + the virtual lights; per-light coefficients are the three vertices' blended by
// weights (per pixel: barycentrics; at a vertex: (v, v, v), (1, 0, 0))
vec3 lights_shade(vec3 n, vec3 x, vec3 w, vec3 emitted, vec3 specular, ivec3 vertices, vec3 weights) {
    vec3 colour = emitted;
    for (int k = 0; k < n_lights; ++k) {
        vec3 term = light_term(k, n, x, w);
        if (all(equal(term, vec3(0.0)))) continue;
        vec3 c = specular;
        if (per_light == 1) {
            c = weights.x * coefficient_at(vertices.x, k);
            if (weights.y != 0.0) c += weights.y * coefficient_at(vertices.y, k);
            if (weights.z != 0.0) c += weights.z * coefficient_at(vertices.z, k);
        }
        colour += term * c;
    }
    return colour;
}
#endif
