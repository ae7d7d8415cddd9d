// The reflection probe's look-up: the same arithmetic as fitting.probe (box_directions,
// texels, look_up); tested against it. Compiles to nothing under VL_NO_PROBE.
// Prepended #define: VL_ALBEDO_POINTS (fitting.probe.ALBEDO_POINTS).
// Uniforms: probe_size (M; 0: no probe), probe_row (the object's first row in probes, an
// RGB32F atlas of M x M blocks stacked in rows), probe_centre, probe_lo, probe_hi (the box).
#ifdef VL_NO_PROBE
vec3 probe_term(vec3 x, vec3 n, vec3 w, vec3 weight) { return vec3(0.0); }
#else
uniform sampler2D probes;
uniform int probe_size;
uniform int probe_row;
uniform vec3 probe_centre;
uniform vec3 probe_lo;
uniform vec3 probe_hi;
uniform float probe_albedo[VL_ALBEDO_POINTS];   // S at n . w = 0, 1 / (VL_ALBEDO_POINTS - 1), ..., 1
#include "box.glsl"
vec2 octahedral(vec3 u) {   // fitting.probe.encode
    vec2 p = u.xy / (abs(u.x) + abs(u.y) + abs(u.z));
    if (u.z < 0.0) p = (1.0 - abs(p.yx)) * vec2(p.x >= 0.0 ? 1.0 : -1.0, p.y >= 0.0 ? 1.0 : -1.0);
    return 0.5 * (p + 1.0);
}
vec3 probe_texel(int i, int j) {   // fitting.probe._wrap: the octahedron's continuity across the border
    int m = probe_size;
    if (i < 0 || i >= m) j = m - 1 - j;
    i = clamp(i, 0, m - 1);
    if (j < 0 || j >= m) i = m - 1 - i;
    j = clamp(j, 0, m - 1);
    return texelFetch(probes, ivec2(i, probe_row + j), 0).rgb;
}
vec3 probe_direction(vec3 x, vec3 n, vec3 w) {   // fitting.probe.box_directions
    vec3 r = 2.0 * dot(n, w) * n - w;
    float rl = length(r);
    if (rl > 0.0) r /= rl;
    return box_direction(x, r, probe_lo, probe_hi, probe_centre);
}
vec3 probe_lookup(vec3 u) {   // fitting.probe.look_up: bilinear, texel centres at (i + 0.5) / M
    vec2 f = octahedral(u) * float(probe_size) - 0.5;
    vec2 f0 = floor(f);
    vec2 t = f - f0;
    int i0 = int(f0.x), j0 = int(f0.y);
    return (1.0 - t.x) * (1.0 - t.y) * probe_texel(i0, j0) + t.x * (1.0 - t.y) * probe_texel(i0 + 1, j0)
         + (1.0 - t.x) * t.y * probe_texel(i0, j0 + 1) + t.x * t.y * probe_texel(i0 + 1, j0 + 1);
}
float probe_albedo_at(vec3 n, vec3 w) {   // fitting.probe.albedo_factor
    float x = clamp(dot(n, w), 0.0, 1.0) * float(VL_ALBEDO_POINTS - 1);
    int i = min(int(floor(x)), VL_ALBEDO_POINTS - 2);
    float f = x - float(i);
    return (1.0 - f) * probe_albedo[i] + f * probe_albedo[i + 1];
}
vec3 probe_term(vec3 x, vec3 n, vec3 w, vec3 weight) {
    if (probe_size == 0) return vec3(0.0);
    return weight * probe_albedo_at(n, w) * probe_lookup(probe_direction(x, n, w));
}
#endif
