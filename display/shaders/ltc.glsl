// A microfacet lobe's highlights by linearly transformed cosines: the same arithmetic as
// radiosity.formats.ltc (cell, view_frame, polygon_cosine, polygon_integral,
// sphere_integral, ndf, smith_g1, lobe_value); tested against it.
//
// Prepended #defines (display.glsl.defines): VL_LTC_ALPHA_MIN, VL_LTC_SPHERE_SIDES,
// VL_LTC_SPHERE_SCALE, VL_LTC_MAX (radiosity.formats.ltc's constants).
// Uniforms:
//   ltc_table     RGBA32F (display.glsl.ltc_texture: radiosity.formats.ltc.table_texture):
//                 row (lobe - 1) S + i, texels 2 j (k00, k02, k20, k22) and 2 j + 1 (norm, schlick)
//   emitter_lobe  1 GGX, 2 Beckmann (0: the Phong lobe of emitters.glsl)
//   emitter_alpha its roughness
uniform sampler2D ltc_table;
uniform int emitter_lobe;
uniform float emitter_alpha;
const float LTC_ALPHA_MIN = VL_LTC_ALPHA_MIN;
const int LTC_SPHERE_SIDES = VL_LTC_SPHERE_SIDES;
const float LTC_SPHERE_SCALE = VL_LTC_SPHERE_SCALE;   // the regular polygon's area the circle's
const int LTC_MAX = VL_LTC_MAX;
const float LTC_PI = 3.141592653589793;
float ltc_texel(int row, int column, int e) {
    return texelFetch(ltc_table, ivec2(2 * column + e / 4, row), 0)[e % 4];
}
// the bilinear read of the cell at (alpha, cos theta_o): k = (k00, k02, k20, k22), m = (norm, schlick)
void ltc_cell(int lobe, float alpha, float cos_o, out vec4 k, out vec2 m) {
    int size = textureSize(ltc_table, 0).x / 2;
    float lo = sqrt(LTC_ALPHA_MIN);
    float u = (sqrt(min(max(alpha, LTC_ALPHA_MIN), 1.0)) - lo) / (1.0 - lo) * float(size - 1);
    float v = sqrt(max(0.0, 1.0 - clamp(cos_o, 0.0, 1.0))) * float(size - 1);
    int i = min(int(u), size - 2);
    int j = min(int(v), size - 2);
    float fu = u - float(i), fv = v - float(j);
    int row = (lobe - 1) * size + i;
    float c[6];
    for (int e = 0; e < 6; ++e) {
        c[e] = (1.0 - fu) * ((1.0 - fv) * ltc_texel(row, j, e) + fv * ltc_texel(row, j + 1, e))
             + fu * ((1.0 - fv) * ltc_texel(row + 1, j, e) + fv * ltc_texel(row + 1, j + 1, e));
    }
    k = vec4(c[0], c[1], c[2], c[3]);
    m = vec2(c[4], c[5]);
}
// unit tangents (t, b) with w in the (t, n) plane on t's side (any pair when w is n)
void ltc_view_frame(vec3 n, vec3 w, out vec3 t, out vec3 b) {
    t = w - dot(w, n) * n;
    float tl = length(t);
    if (!(tl > 1e-12)) {
        float s = n.z >= 0.0 ? 1.0 : -1.0;
        float a = -1.0 / (s + n.z);
        float c = n.x * n.y * a;
        t = vec3(1.0 + s * n.x * n.x * a, s * c, -s * n.x);
        tl = length(t);
    }
    t /= tl;
    b = cross(n, t);
}
// Sutherland-Hodgman: src[:count] clipped to z >= 0 into dst; its count
int ltc_clip(vec3 src[LTC_MAX], int count, out vec3 dst[LTC_MAX]) {
    int out_ = 0;
    for (int i = 0; i < count; ++i) {
        int j = i + 1 < count ? i + 1 : 0;
        float za = src[i].z, zb = src[j].z;
        if (za >= 0.0) dst[out_++] = src[i];
        if ((za >= 0.0) != (zb >= 0.0)) dst[out_++] = src[i] + za / (za - zb) * (src[j] - src[i]);
    }
    return out_;
}
// the vector form factor of the polygon v[:count] (normalised here), its z >= 0
vec3 ltc_edge_sum(vec3 v[LTC_MAX], int count) {
    for (int i = 0; i < count; ++i) {
        float l = length(v[i]);
        if (l > 0.0) v[i] /= l;
    }
    vec3 f = vec3(0.0);
    for (int i = 0; i < count; ++i) {
        vec3 c = cross(v[i], v[i + 1 < count ? i + 1 : 0]);
        float s = length(c);
        if (s > 0.0) f += atan(s, dot(v[i], v[i + 1 < count ? i + 1 : 0])) / s * c;
    }
    return f * ((f.z >= 0.0 ? 1.0 : -1.0) / (2.0 * LTC_PI));
}
// the vector form factor (its z: I) of the polygon local[:count] (relative to the point,
// in the frame (t, b, n)) in the transformed space
vec3 ltc_polygon_cosine(vec3 local[LTC_MAX], int count, vec4 k, float alpha) {
    vec3 clipped[LTC_MAX];
    count = ltc_clip(local, count, clipped);
    if (count < 3) return vec3(0.0);
    float a = max(alpha, LTC_ALPHA_MIN);
    for (int i = 0; i < count; ++i) {
        vec3 p = clipped[i];
        vec3 q = vec3(k.x * p.x + k.y * p.z, p.y, a * (k.z * p.x + k.w * p.z));
        float l = length(q);
        clipped[i] = l > 0.0 ? q / l : q;
    }
    count = ltc_clip(clipped, count, local);
    if (count < 3) return vec3(0.0);
    return ltc_edge_sum(local, count);
}
vec3 ltc_local(vec3 v, vec3 t, vec3 b, vec3 n) { return vec3(dot(v, t), dot(v, b), dot(v, n)); }
vec3 ltc_polygon_integral(int part, int count, vec3 x, vec3 t, vec3 b, vec3 n, vec4 k, float alpha) {
    vec3 q0 = emitter_point(part, 0);
    if (dot(x - q0, cross(emitter_point(part, 1) - q0, emitter_point(part, 2) - q0)) <= 0.0) return vec3(0.0);
    vec3 local[LTC_MAX];
    for (int i = 0; i < count; ++i) local[i] = ltc_local(emitter_point(part, i) - x, t, b, n);
    return ltc_polygon_cosine(local, count, k, alpha);
}
vec3 ltc_sphere_integral(vec3 centre, float radius, vec3 x, vec3 t, vec3 b, vec3 n, vec4 k, float alpha) {
    vec3 c = ltc_local(centre - x, t, b, n);
    float dist = length(c);
    if (!(dist > radius)) return vec3(0.0);
    c /= dist;
    float sin_beta = radius / dist;
    float spread = sin_beta / sqrt(max(1e-30, 1.0 - sin_beta * sin_beta)) * LTC_SPHERE_SCALE;
    float s = c.z >= 0.0 ? 1.0 : -1.0;
    float a = -1.0 / (s + c.z);
    float d = c.x * c.y * a;
    vec3 u = vec3(1.0 + s * c.x * c.x * a, s * d, -s * c.x);
    vec3 v = vec3(d, s + c.y * c.y * a, -c.y);
    vec3 local[LTC_MAX];
    for (int i = 0; i < LTC_SPHERE_SIDES; ++i) {
        float phi = 2.0 * LTC_PI * float(i) / float(LTC_SPHERE_SIDES);
        local[i] = c + (cos(phi) * spread) * u + (sin(phi) * spread) * v;
    }
    return ltc_polygon_cosine(local, LTC_SPHERE_SIDES, k, alpha);
}
float ltc_ndf(int lobe, float alpha, float cos_h) {
    if (cos_h <= 0.0) return 0.0;
    float c2 = min(cos_h * cos_h, 1.0);
    float a2 = alpha * alpha;
    if (lobe == 1) {
        float t = a2 * c2 + 1.0 - c2;
        return a2 / (LTC_PI * t * t);
    }
    return exp(-(1.0 - c2) / (c2 * a2)) / (LTC_PI * a2 * c2 * c2);
}
float ltc_smith_g1(int lobe, float alpha, float cos_v, float cos_vh) {
    if (cos_v * cos_vh <= 0.0) return 0.0;
    float c2 = min(cos_v * cos_v, 1.0);
    float s2 = 1.0 - c2;
    if (s2 <= 0.0) return 1.0;
    if (lobe == 1) return 2.0 / (1.0 + sqrt(1.0 + alpha * alpha * s2 / c2));
    float a = sqrt(c2 / s2) / alpha;
    if (a >= 1.6) return 1.0;
    return (3.535 * a + 2.181 * a * a) / (1.0 + 2.276 * a + 2.577 * a * a);
}
// D G1 G1 / (4 cos theta_o) at wi (towards the light), w (towards the eye); its wi.h in cih
float ltc_lobe_value(int lobe, float alpha, vec3 wi, vec3 w, vec3 n, out float cih) {
    cih = 1.0;
    float ci = dot(wi, n), co = dot(w, n);
    if (!(ci > 0.0 && co > 0.0)) return 0.0;
    vec3 h = wi + w;
    float hl = length(h);
    if (!(hl > 0.0)) return 0.0;
    h /= hl;
    cih = dot(wi, h);
    float g = ltc_smith_g1(lobe, alpha, ci, cih) * ltc_smith_g1(lobe, alpha, co, dot(w, h));
    return ltc_ndf(lobe, alpha, dot(h, n)) * g / (4.0 * co);
}
// T / (norm D) at the polygon's representative direction (its form factor f mapped back by M)
float ltc_lobe_ratio(vec3 f, vec4 k, int lobe, float alpha, float cos_o, float norm) {
    float fl = length(f);
    if (!(fl > 0.0 && norm > 0.0)) return 1.0;
    vec3 u = f / fl;
    float a = max(alpha, LTC_ALPHA_MIN);
    float det = k.x * k.w - k.y * k.z;
    if (!(det > 0.0)) return 1.0;
    float px = a * u.x, pz = u.z;
    vec3 w = normalize(vec3((k.w * px - k.y * pz) / det, a * u.y, (-k.z * px + k.x * pz) / det));
    vec3 aw = vec3((k.x * w.x + k.y * w.z) / a, w.y / a, k.z * w.x + k.w * w.z);
    float al = length(aw);
    if (!(aw.z > 0.0 && al > 0.0)) return 1.0;
    float density = aw.z / al / LTC_PI * (det / (a * a)) / (al * al * al);
    float cih;
    float value = ltc_lobe_value(lobe, alpha, w, vec3(sqrt(max(0.0, 1.0 - cos_o * cos_o)), 0.0, cos_o), vec3(0.0, 0.0, 1.0), cih);
    return value / (norm * density);
}
