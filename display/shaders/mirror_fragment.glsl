// A perfect mirror (display.mirror), its front: ks F(w.n) times what it reflects, F
// Schlick's with mirror_f0 where mirror_fresnel is 1 (else 1): a flat mirror the scene drawn
// from the eye reflected in its plane, a curved one its probe (glass.glsl's
// glass_reflection). Its back is black, as every back.
uniform vec3 eye;
uniform vec3 mirror_ks;
uniform vec3 mirror_f0;
uniform int mirror_fresnel;
in vec3 v_position;
in vec3 v_normal;
out vec4 f_colour;
#include "glass.glsl"
void main() {
    vec3 n = normalize(v_normal);
    vec3 w = normalize(eye - v_position);
    float c = dot(n, w);
    if (c <= 0.0) {
        f_colour = vec4(0.0, 0.0, 0.0, 1.0);
        return;
    }
    vec3 f = vec3(1.0);
    if (mirror_fresnel == 1) f = mirror_f0 + (1.0 - mirror_f0) * pow(1.0 - min(c, 1.0), 5.0);
    f_colour = vec4(mirror_ks * f * glass_reflection(v_position, reflect(-w, n), 0.0), 1.0);
}
