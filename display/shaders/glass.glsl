// Glass at display (display.glass): what a glass surface shows, reflected and transmitted,
// weighted by Fresnel's reflectance, from the object's probe: the scene without its glass,
// drawn from the object's centre into an octahedral map (display.glass.capture), looked up
// parallax-corrected against the scene's box as the fitted probe is (probe.glsl).
// Uniforms: glass_probe (M x M RGB, mipmapped), glass_size (M), glass_centre (where the
// probe was drawn), glass_lo, glass_hi (the scene's box), glass_kind (0 dielectric, 1 thin
// dielectric, 2 rough dielectric), glass_eta (inside over outside), glass_alpha (a rough
// one's roughness: a blurrier level of the map), glass_reflectance, glass_transmittance,
// glass_proxy (0: a slab or a sheet, the light behind it passes straight; 1: a solid,
// refracted in and out through its bounding sphere glass_sphere = (centre, radius)),
// glass_blend (1: what passes straight is the framebuffer behind, blended: alpha carries
// its weight), glass_planar (1: a flat piece's reflection is glass_image, the scene drawn
// with glass_mvp from the eye reflected in its plane, where the point projects), eye.
uniform sampler2D glass_probe;
uniform int glass_size;
uniform vec3 glass_centre;
uniform vec3 glass_lo;
uniform vec3 glass_hi;
uniform int glass_kind;
uniform float glass_eta;
uniform float glass_alpha;
uniform vec3 glass_reflectance;
uniform vec3 glass_transmittance;
uniform int glass_proxy;
uniform vec4 glass_sphere;
uniform int glass_blend;
uniform int glass_planar;
uniform sampler2D glass_image;
uniform mat4 glass_mvp;
float glass_fresnel(float cos_i, float eta) {   // radiosity.scene.microfacet_kernels.fresnel_dielectric
    float c = min(abs(cos_i), 1.0);
    float g2 = eta * eta - 1.0 + c * c;
    if (g2 <= 0.0) return 1.0;
    float g = sqrt(g2);
    float a = (g - c) / (g + c);
    float b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0);
    return 0.5 * a * a * (1.0 + b * b);
}
vec2 glass_octahedral(vec3 u) {   // fitting.probe.encode
    vec2 p = u.xy / (abs(u.x) + abs(u.y) + abs(u.z));
    if (u.z < 0.0) p = (1.0 - abs(p.yx)) * vec2(p.x >= 0.0 ? 1.0 : -1.0, p.y >= 0.0 ? 1.0 : -1.0);
    return 0.5 * (p + 1.0);
}
#include "box.glsl"
vec3 glass_lookup(vec3 x, vec3 r, float lod) {   // from x along unit r, box-projected
    vec3 u = box_direction(x, r, glass_lo, glass_hi, glass_centre);
    return textureLod(glass_probe, glass_octahedral(u), lod).rgb;
}
vec3 glass_reflection(vec3 x, vec3 r, float lod) {   // what is seen along the mirror direction r from x
    if (glass_planar == 1) {
        vec4 p = glass_mvp * vec4(x, 1.0);
        return texture(glass_image, 0.5 * p.xy / p.w + 0.5).rgb;
    }
    return glass_lookup(x, r, lod);
}
// (colour, alpha): alpha 1 but where glass_blend leaves (1 - alpha) of the framebuffer behind
vec4 glass_colour(vec3 x, vec3 n, vec3 w) {
    float eta = glass_eta;
    float c = dot(n, w);
    if (c < 0.0) { n = -n; c = -c; eta = 1.0 / eta; }   // seen from inside
    float lod = glass_kind == 2 ? max(log2(glass_alpha * float(glass_size)), 0.0) : 0.0;
    vec3 reflected = glass_reflectance * glass_reflection(x, reflect(-w, n), lod);
    float f;
    if (glass_kind == 1) {
        f = glass_fresnel(c, glass_eta);
        f = f < 1.0 ? 2.0 * f / (1.0 + f) : 1.0;
    } else {
        f = glass_fresnel(c, eta);
    }
    float through = 1.0 - f;
    if (glass_proxy == 0) {   // a sheet or a slab: straight through
        if (glass_blend == 1) {
            float t = (glass_transmittance.r + glass_transmittance.g + glass_transmittance.b) / 3.0;
            return vec4(f * reflected, 1.0 - through * t);
        }
        return vec4(f * reflected + through * glass_transmittance * glass_lookup(x, -w, lod), 1.0);
    }
    vec3 t1 = refract(-w, n, 1.0 / eta);
    if (dot(t1, t1) == 0.0) return vec4(reflected, 1.0);
    vec3 oc = x - glass_sphere.xyz;
    float b = dot(oc, t1);
    float s = -b + sqrt(max(b * b - (dot(oc, oc) - glass_sphere.w * glass_sphere.w), 0.0));
    vec3 x2 = x + max(s, 0.0) * t1;
    vec3 n2 = normalize(x2 - glass_sphere.xyz);
    vec3 t2 = refract(t1, -n2, eta);
    float f2 = 1.0;
    if (dot(t2, t2) > 0.0) f2 = glass_fresnel(dot(t1, n2), 1.0 / eta);
    vec3 behind = dot(t2, t2) > 0.0 ? glass_lookup(x2, t2, lod) : vec3(0.0);
    // the transmittance scales each of the two refractions, as the path tracer's (Mitsuba's) does
    return vec4(f * reflected + through * (1.0 - f2) * glass_transmittance * glass_transmittance * behind, 1.0);
}
