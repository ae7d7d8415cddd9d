// The reference display: a vertex's radiance grid read for a view direction.
uniform sampler2D radiance;  // every object's radiance, texel base + vertex * D + d
uniform int base;
uniform int grid_n;          // 0 for a diffuse object (D = 1)
const int TEXTURE_WIDTH = VL_TEXTURE_WIDTH;
const float FOUR_OVER_PI = 1.2732395447351628;
vec3 fetch(int index) {
    return texelFetch(radiance, ivec2(index % TEXTURE_WIDTH, index / TEXTURE_WIDTH), 0).rgb;
}
vec2 hemisphere_to_square(vec3 w) {   // radiosity.formats.directions.hemisphere_to_square
    w = normalize(w);
    float z = clamp(w.z, 0.0, 1.0);
    float radius = z > 0.5 ? length(w.xy) / sqrt(1.0 + z) : sqrt(1.0 - z);
    float t = (w.x == 0.0 && w.y == 0.0) ? 0.0 : atan(w.y, w.x) * FOUR_OVER_PI;
    float a;
    float b;
    if (abs(t) < 1.0) { a = radius; b = radius * t; }
    else if (t >= 1.0 && t <= 3.0) { a = radius * (2.0 - t); b = radius; }
    else if (t <= -1.0 && t >= -3.0) { a = radius * (2.0 + t); b = -radius; }
    else { a = -radius; b = t > 0.0 ? radius * (4.0 - t) : -radius * (4.0 + t); }
    return clamp(vec2(a, b), -1.0, 1.0);
}
vec3 lookup(int vertex, vec3 n, vec3 t, vec3 w) {   // radiosity.formats.directions.grid_lookup_weights
    if (grid_n == 0) return fetch(base + vertex);
    int D = grid_n * grid_n;
    vec3 bt = cross(n, t);
    vec2 ab = hemisphere_to_square(vec3(dot(w, t), dot(w, bt), dot(w, n)));
    vec2 xy = (ab + 1.0) * 0.5 * float(grid_n) - 0.5;
    vec2 f0 = floor(xy);
    vec2 f = xy - f0;
    int i0 = clamp(int(f0.x), 0, grid_n - 1);
    int i1 = clamp(int(f0.x) + 1, 0, grid_n - 1);
    int j0 = clamp(int(f0.y), 0, grid_n - 1);
    int j1 = clamp(int(f0.y) + 1, 0, grid_n - 1);
    int row = base + vertex * D;
    vec3 low = mix(fetch(row + j0 * grid_n + i0), fetch(row + j0 * grid_n + i1), f.x);
    vec3 high = mix(fetch(row + j1 * grid_n + i0), fetch(row + j1 * grid_n + i1), f.x);
    return mix(low, high, f.y);
}
