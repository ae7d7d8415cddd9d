// The box-projected ("parallax-corrected") direction of a probe look-up, fitting.probe's
// box_directions: from x (clamped a hair inside the box [lo, hi]) along unit r to where the
// ray leaves the box, seen from the probe's centre; r itself where that point is the centre.
// Shared by the fitted probe (probe.glsl) and glass and mirrors (glass.glsl).
vec3 box_direction(vec3 x, vec3 r, vec3 lo, vec3 hi, vec3 centre) {
    float inset = 1e-6 * length(hi - lo);
    x = clamp(x, lo + inset, hi - inset);
    float t = 1e38;
    for (int k = 0; k < 3; ++k) {
        if (r[k] != 0.0) t = min(t, ((r[k] > 0.0 ? hi[k] : lo[k]) - x[k]) / r[k]);
    }
    t = t < 1e38 ? max(t, 0.0) : 0.0;
    vec3 d = x + t * r - centre;
    float dl = length(d);
    return dl > 0.0 ? d / dl : r;
}
