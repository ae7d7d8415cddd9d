// The emitters' glossy highlights: the same arithmetic as radiosity.physics.emitters
// (highlight_integral, _culled, the visibility of each part blended from the triangle's
// vertices); tested against it. Compiles to nothing under VL_NO_EMITTERS.
// Prepended #defines (display.glsl.defines; VL_STORE_PAGES the renderer's): VL_TEXTURE_WIDTH, VL_CULL,
// VL_MAX_POLYGON_VERTICES, and the quadrature of the emitter nodes N
// (radiosity.physics.emitters.rules): VL_SPHERE_NODES, VL_SPHERE_S, VL_SPHERE_W,
// VL_SECTOR_NODES, VL_SECTOR_S, VL_SECTOR_W (the lists comma-separated).
//
// Uniforms (textures as display.glsl.emitter_table lays them out):
//   emitter_table     RGBA32F, row i = part i: texel 0 (kind: 0 sphere, 1 polygon, 2 point,
//                     3 direction; vertex count, radius, 0), 1 (radiance; a point's
//                     intensity, a direction's irradiance; 0), 2 (bounding centre,
//                     bounding radius), 3 + k (vertex k: a point's position, a
//                     direction's unit direction of travel at k = 0; a point's spot axis
//                     at k = 1 and (cutoff, beam width (radians), 1 for a spot) at k = 2)
//   n_parts           the parts drawn (0: none)
//   own_parts         bit i set: part i belongs to the object (it does not see itself)
//   emitter_ks        the object's specular colour ks (0: a diffuse object: no highlights)
//   emitter_exponent  its modified-Phong exponent
//   emitter_f0        its Schlick F0 (a Fresnel material: ks weighted by F(n.w)); < 0: no Fresnel
//   emitter_lobe, emitter_alpha, ltc_table   a microfacet lobe (ltc.glsl; 0: the Phong lobe
//                     above): emitter_ks then its specular reflectance, emitter_f0 its
//                     exact normal reflectance
//   visibility_base   vertex v's fraction of part i is the red of value visibility_base +
//                     v * n_parts + i: on the desktop, of the renderer's float store
//                     (store.glsl; visibility_base an address, (layer, texel)); on the page, of
//   visibility        an RGB32F texture VL_TEXTURE_WIDTH wide (value i at texel (i % width, i / width))
#include "store.glsl"
#ifdef VL_NO_EMITTERS
vec3 emitter_term(vec3 x, vec3 n, vec3 w, ivec3 vertices, vec3 weights) { return vec3(0.0); }
#else
uniform sampler2D emitter_table;
uniform int n_parts;
uniform int own_parts;
uniform vec3 emitter_ks;
uniform float emitter_exponent;
uniform vec3 emitter_f0;
#ifdef VL_STORE_PAGES
uniform ivec2 visibility_base;
#else
uniform sampler2D visibility;
uniform int visibility_base;
const int VISIBILITY_WIDTH = VL_TEXTURE_WIDTH;
#endif
const float HALF_PI = 1.5707963267948966;
const float TWO_PI = 6.283185307179586;
const float CULL = VL_CULL;
const float U_NODE = 0.28867513459481287;
const int SPHERE_NODES = VL_SPHERE_NODES;
const float SPHERE_S[VL_SPHERE_NODES] = float[VL_SPHERE_NODES](VL_SPHERE_S);
const float SPHERE_W[VL_SPHERE_NODES] = float[VL_SPHERE_NODES](VL_SPHERE_W);
const int SECTOR_NODES = VL_SECTOR_NODES;
const float SECTOR_S[VL_SECTOR_NODES] = float[VL_SECTOR_NODES](VL_SECTOR_S);
const float SECTOR_W[VL_SECTOR_NODES] = float[VL_SECTOR_NODES](VL_SECTOR_W);
float atan2_(float y, float x) {   // numba's atan2: 0 at (0, 0), where GLSL's atan is undefined
    return (x == 0.0 && y == 0.0) ? 0.0 : atan(y, x);
}
float log1m(float v) {   // log(1 - v), exact for small v
    if (v < 0.01) return -v * (1.0 + v * (0.5 + v * (1.0 / 3.0 + v * 0.25)));
    return log(1.0 - v);
}
float lobe_cdf(float theta, float p1) {   // cos^p1 theta through the versine
    if (theta >= HALF_PI) return 0.0;
    if (theta <= 0.0) return 1.0;
    float h = sin(0.5 * theta);
    return exp(p1 * log1m(2.0 * h * h));
}
float lobe_slice(float lo, float hi, float p1, float rn, float dn) {
    float u1 = lobe_cdf(lo, p1);
    float u2 = lobe_cdf(hi, p1);
    float du = u1 - u2;
    if (!(du > 0.0)) return 0.0;
    float mean = 0.0;
    for (int k = 0; k < 2; ++k) {
        float u = 0.5 * (u1 + u2) + (k == 0 ? U_NODE : -U_NODE) * du;
        float c = u > 0.0 ? exp(log(u) / p1) : 0.0;
        float g = c * rn + sqrt(max(0.0, 1.0 - c * c)) * dn;
        if (g > 0.0) mean += 0.5 * g;
    }
    return du * mean;
}
void lobe_frame(vec3 r, out vec3 t, out vec3 b) {   // Duff et al. 2017
    float s = r.z >= 0.0 ? 1.0 : -1.0;
    float a = -1.0 / (s + r.z);
    float c = r.x * r.y * a;
    t = vec3(1.0 + s * r.x * r.x * a, s * c, -s * r.x);
    b = vec3(c, s + r.y * r.y * a, -r.y);
}
float sphere_integral(vec3 centre, float radius, vec3 x, vec3 n, vec3 r, float p) {
    vec3 t, b;
    lobe_frame(r, t, b);
    float rn = dot(r, n), tn = dot(t, n), bn = dot(b, n);
    float p1 = p + 1.0;
    vec3 c = centre - x;
    float dist = length(c);
    if (!(dist > radius)) return 0.0;
    c /= dist;
    float sin_beta = radius / dist;
    float gamma = atan2_(length(cross(r, c)), dot(r, c));
    float beta = asin(sin_beta);
    if (gamma - beta >= HALF_PI) return 0.0;
    bool full = gamma <= beta;
    float half_ = full ? 0.0 : asin(min(sin_beta / sin(gamma), 1.0));
    float mid = atan2_(dot(c, b), dot(c, t));
    float total = 0.0;
    for (int k = 0; k < SPHERE_NODES; ++k) {
        float phi, weight;
        if (full) {
            phi = TWO_PI * (float(k) + 0.5) / float(SPHERE_NODES);
            weight = TWO_PI / float(SPHERE_NODES);
        } else {
            phi = mid + half_ * sin(HALF_PI * SPHERE_S[k]);
            weight = SPHERE_W[k] * half_ * HALF_PI * cos(HALF_PI * SPHERE_S[k]);
        }
        float cp = cos(phi), sp = sin(phi);
        vec3 d = cp * t + sp * b;
        float a_ = dot(r, c);
        float b_ = dot(d, c);
        float off = dot(cross(r, d), c);
        float inside = sin_beta * sin_beta - off * off;
        float rho = sqrt(a_ * a_ + b_ * b_);
        if (!(inside > 0.0 && rho > 0.0)) continue;
        float kappa = asin(min(sqrt(inside) / rho, 1.0));
        float delta = atan2_(b_, a_);
        float lo = max(0.0, delta - kappa);
        float hi = min(HALF_PI, delta + kappa);
        if (hi > lo) total += weight * lobe_slice(lo, hi, p1, rn, cp * tn + sp * bn);
    }
    return total / p1;
}
vec3 emitter_point(int part, int k) { return texelFetch(emitter_table, ivec2(3 + k, part), 0).xyz; }
#include "ltc.glsl"
float polygon_integral(int part, int count, vec3 x, vec3 n, vec3 r, float p) {
    vec3 t, b;
    lobe_frame(r, t, b);
    float rn = dot(r, n), tn = dot(t, n), bn = dot(b, n);
    float p1 = p + 1.0;
    vec3 q0 = emitter_point(part, 0);
    if (dot(x - q0, cross(emitter_point(part, 1) - q0, emitter_point(part, 2) - q0)) <= 0.0) return 0.0;
    vec3 m[VL_MAX_POLYGON_VERTICES];
    float pm[VL_MAX_POLYGON_VERTICES];
    float azimuth[VL_MAX_POLYGON_VERTICES + 1];
    bool ahead = false, pos = true, neg = true;
    vec3 ac = vec3(0.0);
    for (int i = 0; i < count; ++i) {
        vec3 a = emitter_point(part, i) - x;
        vec3 g = emitter_point(part, i + 1 < count ? i + 1 : 0) - x;
        ahead = ahead || dot(a, r) > 0.0;
        ac += a;
        vec3 mi = cross(g, a);
        float ml = length(mi);
        m[i] = ml > 0.0 ? mi / ml : mi;
        pm[i] = dot(m[i], r);
        pos = pos && pm[i] >= 0.0;
        neg = neg && pm[i] <= 0.0;
    }
    if (!ahead) return 0.0;
    float ref = atan2_(dot(ac, b), dot(ac, t));
    for (int i = 0; i < count; ++i) {
        vec3 a = emitter_point(part, i) - x;
        float d = atan2_(dot(a, b), dot(a, t)) - ref;
        azimuth[i] = d - TWO_PI * floor((d + 3.141592653589793) / TWO_PI);
    }
    for (int i = 1; i < count; ++i) {
        float v = azimuth[i];
        int j = i - 1;
        while (j >= 0 && azimuth[j] > v) { azimuth[j + 1] = azimuth[j]; --j; }
        azimuth[j + 1] = v;
    }
    int sectors = count - 1;
    if (pos || neg) { azimuth[count] = azimuth[0] + TWO_PI; sectors = count; }
    float total = 0.0;
    for (int sector = 0; sector < sectors; ++sector) {
        float half_ = 0.5 * (azimuth[sector + 1] - azimuth[sector]);
        if (!(half_ > 0.0)) continue;
        float mid = ref + 0.5 * (azimuth[sector + 1] + azimuth[sector]);
        for (int k = 0; k < SECTOR_NODES; ++k) {
            float phi = mid + half_ * SECTOR_S[k];
            float cp = cos(phi), sp = sin(phi);
            vec3 d = cp * t + sp * b;
            float lo = 0.0, hi = HALF_PI;
            for (int i = 0; i < count; ++i) {
                float p_ = pm[i], q_ = dot(d, m[i]);
                if (p_ >= 0.0 && q_ >= 0.0) continue;
                if (p_ < 0.0 && q_ < 0.0) { hi = -1.0; break; }
                if (p_ >= 0.0) hi = min(hi, atan2_(p_, -q_));
                else lo = max(lo, atan2_(-p_, q_));
            }
            if (hi > lo) total += SECTOR_W[k] * half_ * lobe_slice(lo, hi, p1, rn, cp * tn + sp * bn);
        }
    }
    return total / p1;
}
float spot_falloff(float theta, float cutoff, float beam) {   // Mitsuba 3's spot profile at theta from its axis
    if (!(theta < cutoff)) return 0.0;
    if (theta <= beam) return 1.0;
    return (cutoff - theta) / (cutoff - beam);
}
// where a delta part's light comes from at x: the unit wi toward it, and the factor its
// Le is weighted by (1 / d^2 times the spot's profile for a point, 1 for a direction; 0:
// unusable) (radiosity.physics.emitters.delta_incidence)
float delta_incidence(int part, bool direction, vec3 x, out vec3 wi) {
    vec3 q = emitter_point(part, 0);
    wi = -q;
    if (direction) return 1.0;
    vec3 to = q - x;
    float d2 = dot(to, to);
    if (!(d2 > 0.0)) return 0.0;
    wi = to / sqrt(d2);
    float scale = 1.0 / d2;
    vec3 spot = emitter_point(part, 2);
    vec3 axis = emitter_point(part, 1);
    if (spot.z > 0.0) scale *= spot_falloff(atan2_(length(cross(wi, axis)), -dot(wi, axis)), spot.x, spot.y);
    return scale;
}
// a delta part's J: the lobe and the cosine at its one direction, times 1 / d^2 and the
// spot's profile for a point (radiosity.physics.emitters.delta_integral)
float delta_integral(int part, bool direction, vec3 x, vec3 n, vec3 r, float p) {
    vec3 wi;
    float scale = delta_incidence(part, direction, x, wi);
    float cos_n = dot(wi, n), cos_a = dot(wi, r);
    if (!(cos_n > 0.0 && cos_a > 0.0 && scale > 0.0)) return 0.0;
    return scale * cos_n * pow(min(cos_a, 1.0), p);
}
bool emitter_culled(vec4 bound, vec3 x, vec3 r, float p) {
    vec3 c = bound.xyz - x;
    float dist = length(c);
    if (!(dist > bound.w)) return false;
    float nearest = atan2_(length(cross(r, c)), dot(r, c)) - asin(bound.w / dist);
    return nearest > 0.0 && lobe_cdf(nearest, p) < CULL;
}
float visibility_at(int vertex, int part) {
#ifdef VL_STORE_PAGES
    return store_value(visibility_base, vertex, n_parts, part).r;
#else
    int i = visibility_base + vertex * n_parts + part;
    return texelFetch(visibility, ivec2(i % VISIBILITY_WIDTH, i / VISIBILITY_WIDTH), 0).r;
#endif
}
float part_visibility(int i, ivec3 vertices, vec3 weights) {
    float v = weights.x * visibility_at(vertices.x, i);
    if (weights.y != 0.0) v += weights.y * visibility_at(vertices.y, i);
    if (weights.z != 0.0) v += weights.z * visibility_at(vertices.z, i);
    return v;
}
// a microfacet lobe's highlights (radiosity.physics.emitters._microfacet_radiance): an
// area part by linearly transformed cosines with Schlick's curve through emitter_f0
// integrated over the lobe, a delta part the lobe at its direction with F(wi.h)
vec3 microfacet_term(vec3 x, vec3 n, vec3 w, ivec3 vertices, vec3 weights) {
    vec3 colour = vec3(0.0);
    float wn = dot(n, w);
    if (!(wn > 0.0)) return colour;
    vec4 k;
    vec2 m;
    ltc_cell(emitter_lobe, emitter_alpha, wn, k, m);
    vec3 area = emitter_ks * (emitter_f0 * m.x + (1.0 - emitter_f0) * m.y);
    vec3 t, b;
    ltc_view_frame(n, w, t, b);
    vec3 r = 2.0 * wn * n - w;
    for (int i = 0; i < n_parts; ++i) {
        if (((own_parts >> i) & 1) == 1) continue;
        float v = part_visibility(i, vertices, weights);
        if (!(v > 0.0)) continue;
        vec4 head = texelFetch(emitter_table, ivec2(0, i), 0);
        if (head.x < 1.5 && ltc_culled(emitter_lobe, emitter_alpha, texelFetch(emitter_table, ivec2(2, i), 0), x, n, r)) continue;
        vec3 le = texelFetch(emitter_table, ivec2(1, i), 0).rgb;
        if (head.x > 1.5) {   // a point or a direction
            vec3 wi;
            float scale = delta_incidence(i, head.x > 2.5, x, wi);
            if (!(scale > 0.0)) continue;
            float cih;
            float value = ltc_lobe_value(emitter_lobe, emitter_alpha, wi, w, n, cih);
            float x5 = pow(1.0 - clamp(cih, 0.0, 1.0), 5.0);
            colour += (value * scale * v) * emitter_ks * (emitter_f0 + (1.0 - emitter_f0) * x5) * le;
            continue;
        }
        float j = ltc_part_integral(i, head, x, t, b, n, k, emitter_lobe, emitter_alpha, wn, m.x);
        colour += (j * v) * area * le;
    }
    return colour;
}
// the emitters' highlights at x (unit normal n, unit w towards the eye), each part's
// visibility blended from the vertices by weights (per pixel: barycentrics; at a vertex:
// (v, v, v), (1, 0, 0))
vec3 emitter_term(vec3 x, vec3 n, vec3 w, ivec3 vertices, vec3 weights) {
    vec3 colour = vec3(0.0);
    if (n_parts == 0 || all(equal(emitter_ks, vec3(0.0)))) return colour;
    if (emitter_lobe != 0) return microfacet_term(x, n, w, vertices, weights);
    vec3 r = 2.0 * dot(n, w) * n - w;
    float rl = length(r);
    if (!(rl > 0.0)) return colour;
    r /= rl;
    float p = emitter_exponent;
    float norm = (p + 2.0) / TWO_PI;
    vec3 ks = emitter_ks;
    if (emitter_f0.x >= 0.0) {   // Fresnel: Schlick's F at the highlight's direction (wi.h = n.w at r)
        float x5 = pow(1.0 - clamp(dot(n, w), 0.0, 1.0), 5.0);
        ks *= emitter_f0 + (1.0 - emitter_f0) * x5;
    }
    for (int i = 0; i < n_parts; ++i) {
        if (((own_parts >> i) & 1) == 1) continue;
        float v = part_visibility(i, vertices, weights);
        if (!(v > 0.0)) continue;
        vec4 head = texelFetch(emitter_table, ivec2(0, i), 0);
        float j;
        if (head.x > 1.5) {   // a point or a direction: exact, never culled
            j = delta_integral(i, head.x > 2.5, x, n, r, p);
        } else {
            vec4 bound = texelFetch(emitter_table, ivec2(2, i), 0);
            if (emitter_culled(bound, x, r, p)) continue;
            j = head.x < 0.5 ? sphere_integral(emitter_point(i, 0), head.z, x, n, r, p)
                             : polygon_integral(i, int(head.y + 0.5), x, n, r, p);
        }
        colour += (j * norm * v) * ks * texelFetch(emitter_table, ivec2(1, i), 0).rgb;
    }
    return colour;
}
#endif
