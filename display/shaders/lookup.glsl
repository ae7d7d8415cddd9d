// The reference display: a vertex's radiance grid read for a view direction. The grids
// are in the renderer's float store (store.glsl): value d of vertex v of the object at
// store address base + v * D + d (D = grid_n * grid_n; a diffuse object D = 1).
#include "store.glsl"
uniform ivec2 base;          // the object's first value: (layer, texel) in the store
uniform int grid_n;          // 0 for a diffuse object (D = 1)
const float FOUR_OVER_PI = 1.2732395447351628;
vec2 hemisphere_to_square(vec3 w) {   // radiosity.physics.directions.hemisphere_to_square
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
vec3 lookup(int vertex, vec3 n, vec3 t, vec3 w) {   // radiosity.physics.directions.grid_lookup_weights
    if (grid_n == 0) return store_value(base, vertex, 1, 0).rgb;
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
    ivec2 row = store_start(base, vertex, D);   // the vertex's grid, d = j * grid_n + i
    vec3 low = mix(store_fetch(store_step(row, j0 * grid_n + i0)).rgb, store_fetch(store_step(row, j0 * grid_n + i1)).rgb, f.x);
    vec3 high = mix(store_fetch(store_step(row, j1 * grid_n + i0)).rgb, store_fetch(store_step(row, j1 * grid_n + i1)).rgb, f.x);
    return mix(low, high, f.y);
}
