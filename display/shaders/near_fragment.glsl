// A near mirror (display.mirror.near_mirror_of): a flat microfacet surface so sharp that
// what it reflects is drawn as a flat mirror's is, the scene seen from the eye reflected in
// its plane (glass.glsl's glass_reflection with glass_planar 1), weighted by its lobe's
// albedo with Fresnel, ks (F0 norm + (1 - F0) schlick) at (alpha, n . w) from the table
// (ltc_table.glsl); over its own part: the base colour per vertex (display.mirror.near_base:
// a plastic's substrate, leaving the interface as 1 - F(n . w, near_eta); a conductor's
// least radiance; or the fit's emitted colour, near_eta 0) and a textured object's
// kd texture(uv) E / pi. Its back is black, as every back.
uniform vec3 eye;
uniform vec3 near_ks;
uniform vec3 near_f0;
uniform int near_lobe;
uniform float near_alpha;
uniform float near_eta;      // the substrate's interface (a plastic's eta), 0: none
in vec3 v_position;
in vec3 v_normal;
in vec3 v_base;
in vec2 v_uv;
in vec3 v_irradiance;
out vec4 f_colour;
#include "glass.glsl"
#include "ltc_table.glsl"
#include "textured.glsl"
vec3 near_colour(vec3 n, vec3 w, float c) {   // the front, seen at c = n . w > 0
    vec4 k;
    vec2 m;
    ltc_cell(near_lobe, near_alpha, c, k, m);
    vec3 colour = v_base * (near_eta > 0.0 ? 1.0 - glass_fresnel(c, near_eta) : 1.0) + near_ks * (near_f0 * m.x + (1.0 - near_f0) * m.y) * glass_reflection(v_position, reflect(-w, n), 0.0);
#ifdef VL_TEXTURED
    colour += textured_term(v_uv, v_irradiance);
#endif
    return colour;
}
void main() {
    vec3 n = normalize(v_normal);
    vec3 w = normalize(eye - v_position);
    float c = dot(n, w);
    f_colour = vec4(c > 0.0 ? near_colour(n, w, c) : vec3(0.0), 1.0);
}
