// A microfacet lobe's highlights by linearly transformed cosines: the same arithmetic as
// radiosity.physics.ltc (cell, view_frame, polygon_cosine, polygon_integral,
// sphere_integral, ndf, smith_g1, lobe_value); tested against it.
//
// Prepended #defines (display.glsl.defines): VL_LTC_ALPHA_MIN, VL_LTC_SPHERE_SIDES,
// VL_LTC_SPHERE_SCALE, VL_LTC_CULL, VL_LTC_MAX_RATIO (radiosity.physics.ltc's constants).
// Uniforms:
//   ltc_table     RGBA32F (display.glsl.ltc_texture: radiosity.physics.ltc.table_texture):
//                 row (lobe - 1) S + i, texels 2 j (k00, k02, k20, k22) and 2 j + 1 (norm, schlick)
//   emitter_lobe  1 GGX, 2 Beckmann (0: the Phong lobe of emitters.glsl)
//   emitter_alpha its roughness
#include "ltc_table.glsl"
uniform int emitter_lobe;
uniform float emitter_alpha;
const int LTC_SPHERE_SIDES = VL_LTC_SPHERE_SIDES;
const float LTC_SPHERE_SCALE = VL_LTC_SPHERE_SCALE;   // the regular polygon's area the circle's
const float LTC_CULL = VL_LTC_CULL;
const float LTC_MAX_RATIO = VL_LTC_MAX_RATIO;
const float LTC_PI = 3.141592653589793;
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
vec3 ltc_edge(vec3 a, vec3 b) {   // one edge's term theta (a x b) / |a x b| (a, b unit)
    vec3 c = cross(a, b);
    float s = length(c);
    return s > 0.0 ? atan(s, dot(a, b)) / s * c : vec3(0.0);
}
vec3 ltc_mapped(vec3 p, vec4 k, float a) {   // alpha M^-1 p, normalised
    vec3 q = vec3(k.x * p.x + k.y * p.z, p.y, a * (k.z * p.x + k.w * p.z));
    float l = length(q);
    return l > 0.0 ? q / l : q;
}
vec3 ltc_crossing(vec3 a, vec3 b) {   // where a b meets z = 0 (a, b on either side), normalised
    float s = a.z / (a.z - b.z);
    vec2 q = a.xy + s * (b.xy - a.xy);
    float l = length(q);
    return vec3(l > 0.0 ? q / l : q, 0.0);
}
// one edge prev -> cur (mapped) of a polygon clipped edge by edge to z >= 0: its term added
// to f, where it leaves (leave) or comes back (enter) noted, crossings counted
void ltc_clip_edge(vec3 prev, vec3 cur, inout vec3 f, inout vec3 leave, inout vec3 enter, inout int crossed) {
    bool above_a = prev.z >= 0.0, above_b = cur.z >= 0.0;
    if (above_a && above_b) {
        f += ltc_edge(prev, cur);
    } else if (above_a) {
        leave = ltc_crossing(prev, cur);
        f += ltc_edge(prev, leave);
        crossed += 1;
    } else if (above_b) {
        enter = ltc_crossing(prev, cur);
        f += ltc_edge(enter, cur);
        crossed += 1;
    }
}
vec3 ltc_closed(vec3 f, vec3 leave, vec3 enter, int crossed) {   // the edge along the horizon, oriented
    if (crossed == 2) f += ltc_edge(leave, enter);
    return f * ((f.z >= 0.0 ? 1.0 : -1.0) / (2.0 * LTC_PI));
}
// the vector form factor of the triangle (a, b, c) (local, unmapped)
vec3 ltc_triangle(vec3 a, vec3 b, vec3 c, vec4 k, float alpha) {
    float s = max(alpha, LTC_ALPHA_MIN);
    vec3 p = ltc_mapped(a, k, s), q = ltc_mapped(b, k, s), r = ltc_mapped(c, k, s);
    vec3 f = vec3(0.0), leave = vec3(0.0), enter = vec3(0.0);
    int crossed = 0;
    ltc_clip_edge(p, q, f, leave, enter, crossed);
    ltc_clip_edge(q, r, f, leave, enter, crossed);
    ltc_clip_edge(r, p, f, leave, enter, crossed);
    return ltc_closed(f, leave, enter, crossed);
}
// the unit direction (local) a vector form factor f of the transformed space stands for: M f
vec3 ltc_representative(vec3 f, vec4 k, float alpha) {
    float fl = length(f);
    float det = k.x * k.w - k.y * k.z;
    if (!(fl > 0.0 && det > 0.0)) return vec3(0.0);
    float a = max(alpha, LTC_ALPHA_MIN);
    float px = a * f.x / fl, pz = f.z / fl;
    return normalize(vec3((k.w * px - k.y * pz) / det, a * f.y / fl, (-k.z * px + k.x * pz) / det));
}
vec3 ltc_local(vec3 v, vec3 t, vec3 b, vec3 n) { return vec3(dot(v, t), dot(v, b), dot(v, n)); }
// vertex i of part `part`'s polygon relative to x in the frame (t, b, n); a sphere (head.x
// 0, radius head.z): of the regular LTC_SPHERE_SIDES-gon of the same area as its cap across
// the cone that bounds it (c its unit direction, u, v across it, spread the polygon's radius)
vec3 ltc_vertex(int part, int i, vec3 x, vec3 t, vec3 b, vec3 n, bool sphere, vec3 c, vec3 u, vec3 v, float spread) {
    if (!sphere) return ltc_local(emitter_point(part, i) - x, t, b, n);
    float phi = 2.0 * LTC_PI * float(i) / float(LTC_SPHERE_SIDES);
    return c + (cos(phi) * spread) * u + (sin(phi) * spread) * v;
}
// a sphere part's regular polygon (ltc_vertex): its unit direction c, the pair (u, v)
// across it and the polygon's radius spread; false from inside the lamp
bool ltc_sphere_polygon(int part, vec4 head, vec3 x, vec3 t, vec3 b, vec3 n, out vec3 c, out vec3 u, out vec3 v,
                        out float spread) {
    c = ltc_local(emitter_point(part, 0) - x, t, b, n);
    u = vec3(0.0);
    v = vec3(0.0);
    spread = 0.0;
    float dist = length(c);
    if (!(dist > head.z)) return false;
    c /= dist;
    float sin_beta = head.z / dist;
    spread = sin_beta / sqrt(max(1e-30, 1.0 - sin_beta * sin_beta)) * LTC_SPHERE_SCALE;
    float s = c.z >= 0.0 ? 1.0 : -1.0;
    float a = -1.0 / (s + c.z);
    float d = c.x * c.y * a;
    u = vec3(1.0 + s * c.x * c.x * a, s * d, -s * c.x);
    v = vec3(d, s + c.y * c.y * a, -c.y);
    return true;
}
// The vector form factor (its z: I) of part `part` (head: its table row's texel 0) at x in
// the frame (t, b, n) (radiosity.physics.ltc.polygon_integral, sphere_integral,
// polygon_cosine): each vertex mapped by alpha M^-1, the polygon clipped to the transformed
// cosine's horizon edge by edge, the edges' terms summed. No arrays: llvmpipe keeps them
// slowly, and a vertex is read or made where it is needed.
vec3 ltc_part_form_factor(int part, vec4 head, vec3 x, vec3 t, vec3 b, vec3 n, vec4 k, float alpha) {
    bool sphere = head.x < 0.5;
    vec3 c = vec3(0.0), u = vec3(0.0), v = vec3(0.0);
    float spread = 0.0;
    int count;
    if (sphere) {
        if (!ltc_sphere_polygon(part, head, x, t, b, n, c, u, v, spread)) return vec3(0.0);
        count = LTC_SPHERE_SIDES;
    } else {
        count = int(head.y + 0.5);
        vec3 q0 = emitter_point(part, 0);
        if (dot(x - q0, cross(emitter_point(part, 1) - q0, emitter_point(part, 2) - q0)) <= 0.0) return vec3(0.0);
    }
    float a = max(alpha, LTC_ALPHA_MIN);
    vec3 first = ltc_mapped(ltc_vertex(part, 0, x, t, b, n, sphere, c, u, v, spread), k, a);
    vec3 prev = first;
    vec3 leave = vec3(0.0), enter = vec3(0.0);
    int crossed = 0;
    vec3 f = vec3(0.0);
    for (int i = 0; i < count; ++i) {
        vec3 cur = i + 1 == count ? first : ltc_mapped(ltc_vertex(part, i + 1, x, t, b, n, sphere, c, u, v, spread), k, a);
        ltc_clip_edge(prev, cur, f, leave, enter, crossed);
        prev = cur;
    }
    return ltc_closed(f, leave, enter, crossed);
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
// radiosity.physics.ltc.culled: the part's bounding sphere wholly below the tangent plane,
// or (alpha < 0.5) nowhere near enough the mirror direction r for D to reach LTC_CULL of its peak
bool ltc_culled(int lobe, float alpha, vec4 bound, vec3 x, vec3 n, vec3 r) {
    vec3 c = bound.xyz - x;
    if (dot(c, n) < -bound.w) return true;
    if (!(alpha < 0.5)) return false;
    float dist = length(c);
    if (!(dist > bound.w)) return false;
    float nearest = atan2_(length(cross(r, c)), dot(r, c)) - asin(bound.w / dist);
    if (!(nearest > 0.0)) return false;
    return ltc_ndf(lobe, alpha, cos(min(0.5 * nearest, 0.5 * LTC_PI))) < LTC_CULL * ltc_ndf(lobe, alpha, 1.0);
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
    vec3 w = ltc_representative(f, k, alpha);
    if (!(norm > 0.0) || w == vec3(0.0)) return 1.0;
    float a = max(alpha, LTC_ALPHA_MIN);
    float det = k.x * k.w - k.y * k.z;
    vec3 aw = vec3((k.x * w.x + k.y * w.z) / a, w.y / a, k.z * w.x + k.w * w.z);
    float al = length(aw);
    if (!(aw.z > 0.0 && al > 0.0)) return 1.0;
    float density = aw.z / al / LTC_PI * (det / (a * a)) / (al * al * al);
    float cih;
    float value = ltc_lobe_value(lobe, alpha, w, vec3(sqrt(max(0.0, 1.0 - cos_o * cos_o)), 0.0, cos_o), vec3(0.0, 0.0, 1.0), cih);
    return min(value / (norm * density), LTC_MAX_RATIO);
}
// I of part `part` corrected towards the lobe (radiosity.physics.ltc.fan_integral): the fan of
// triangles from the part's representative direction to each edge, each triangle's integral
// times ltc_lobe_ratio at its own representative direction
float ltc_part_integral(int part, vec4 head, vec3 x, vec3 t, vec3 b, vec3 n, vec4 k, int lobe, float alpha, float cos_o,
                        float norm) {
    vec3 f = ltc_part_form_factor(part, head, x, t, b, n, k, alpha);
    if (!(f.z > 0.0)) return 0.0;
    vec3 centre = ltc_representative(f, k, alpha);
    bool sphere = head.x < 0.5;
    vec3 c = vec3(0.0), u = vec3(0.0), v = vec3(0.0);
    float spread = 0.0;
    int count = sphere ? LTC_SPHERE_SIDES : int(head.y + 0.5);
    if (sphere) ltc_sphere_polygon(part, head, x, t, b, n, c, u, v, spread);   // ltc_part_form_factor's polygon
    vec3 first = ltc_vertex(part, 0, x, t, b, n, sphere, c, u, v, spread);
    // the fan's centre: the representative direction where it lies inside the polygon, else
    // the mean of the vertices' directions (radiosity.physics.ltc._fan_centre)
    bool pos = true, neg = true;
    vec3 mean = vec3(0.0);
    vec3 prev = first;
    for (int i = 0; i < count; ++i) {
        vec3 cur = i + 1 == count ? first : ltc_vertex(part, i + 1, x, t, b, n, sphere, c, u, v, spread);
        float side = dot(centre, cross(prev, cur));
        pos = pos && side >= 0.0;
        neg = neg && side <= 0.0;
        float l = length(prev);
        if (l > 0.0) mean += prev / l;
        prev = cur;
    }
    if (!(pos || neg) && length(mean) > 0.0) centre = normalize(mean);
    prev = first;
    float total = 0.0;
    for (int i = 0; i < count; ++i) {
        vec3 cur = i + 1 == count ? first : ltc_vertex(part, i + 1, x, t, b, n, sphere, c, u, v, spread);
        vec3 ft = ltc_triangle(centre, prev, cur, k, alpha);
        if (ft.z > 0.0) total += ft.z * ltc_lobe_ratio(ft, k, lobe, alpha, cos_o, norm);
        prev = cur;
    }
    return min(total, LTC_MAX_RATIO * f.z);   // the triangles' sum is the polygon's, each ratio at most LTC_MAX_RATIO
}
