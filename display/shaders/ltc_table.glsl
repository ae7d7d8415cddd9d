// The table of linearly transformed cosines and its bilinear read (radiosity.physics.ltc.cell),
// shared by the highlights (ltc.glsl) and the near mirrors (near_fragment.glsl).
// Prepended #define: VL_LTC_ALPHA_MIN. Uniform: ltc_table, RGBA32F
// (display.glsl.ltc_texture: radiosity.physics.ltc.table_texture): row (lobe - 1) S + i,
// texels 2 j (k00, k02, k20, k22) and 2 j + 1 (norm, schlick).
uniform sampler2D ltc_table;
const float LTC_ALPHA_MIN = VL_LTC_ALPHA_MIN;
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
    float w00 = (1.0 - fu) * (1.0 - fv), w01 = (1.0 - fu) * fv, w10 = fu * (1.0 - fv), w11 = fu * fv;
    k = w00 * texelFetch(ltc_table, ivec2(2 * j, row), 0) + w01 * texelFetch(ltc_table, ivec2(2 * j + 2, row), 0)
      + w10 * texelFetch(ltc_table, ivec2(2 * j, row + 1), 0) + w11 * texelFetch(ltc_table, ivec2(2 * j + 2, row + 1), 0);
    m = (w00 * texelFetch(ltc_table, ivec2(2 * j + 1, row), 0) + w01 * texelFetch(ltc_table, ivec2(2 * j + 3, row), 0)
       + w10 * texelFetch(ltc_table, ivec2(2 * j + 1, row + 1), 0) + w11 * texelFetch(ltc_table, ivec2(2 * j + 3, row + 1), 0)).xy;
}
