// The renderer's float store (display.renderer.StoreLayout): the solution's radiance grids,
// the fitted per-light coefficients and the emitters' visibility of every object, one
// RGB32F value a texel, in VL_STORE_PAGES 2D array textures ("pages", each a sampler of
// its own). Value i of the store (a count that may pass 2^31) lies in layer g = i / L at
// texel t = i % L, that is (t % W, t / W), with W = VL_TEXTURE_WIDTH texels a row and
// L = 2^store_shift texels a layer, at least 2^16 (W and L powers of two: every division
// here is a shift); layer g is layer g % store_layers of page g / store_layers. A value
// is never named by i: a block of values starts at an address (g, t), and store_start
// finds a row of the block in 32-bit unsigned arithmetic whose every product and sum
// stays below 2^32.
// Compiled where the renderer defines VL_STORE_PAGES (the desktop); the web page keeps
// one 2D texture per object (lights.glsl, emitters.glsl, their #else branches).
#ifdef VL_STORE_PAGES
uniform sampler2DArray store[VL_STORE_PAGES];
uniform int store_shift;    // log2 of L, the texels of a layer: 16 or more
uniform int store_layers;   // layers a page (the last page may have fewer)
const uint STORE_WIDTH = uint(VL_TEXTURE_WIDTH);
// the address of value base + row * stride: base an address, 0 <= row < 2^31,
// 1 <= stride <= 2^16 (row * stride = high * 2^16 + low, high < 2^31, low < 2^32)
ivec2 store_start(ivec2 base, int row, int stride) {
    uint shift = uint(store_shift);
    uint mask = (1u << shift) - 1u;     // t % L
    uint high = (uint(row) >> 16) * uint(stride);
    uint low = (uint(row) & 0xFFFFu) * uint(stride);
    // high 2^16 = (high >> (shift - 16)) L + (high % 2^(shift - 16)) 2^16
    uint t = uint(base.y) + ((high & (mask >> 16)) << 16) + (low & mask);   // < 3 L
    uint g = uint(base.x) + (high >> (shift - 16u)) + (low >> shift) + (t >> shift);
    return ivec2(int(g), int(t & mask));
}
// the address offset values after address at (0 <= offset <= L)
ivec2 store_step(ivec2 at, int offset) {
    uint t = uint(at.y) + uint(offset);
    uint mask = (1u << uint(store_shift)) - 1u;
    return t <= mask ? ivec2(at.x, int(t)) : ivec2(at.x + 1, int(t & mask));
}
// the value at an address
vec4 store_fetch(ivec2 at) {
    ivec2 xy = ivec2(int(uint(at.y) % STORE_WIDTH), int(uint(at.y) / STORE_WIDTH));
#if VL_STORE_PAGES == 1
    return texelFetch(store[0], ivec3(xy, at.x), 0);
#else
    // page p holds layers p store_layers to (p + 1) store_layers - 1: the last page whose first layer is at most g
    int g = at.x;
#if VL_STORE_PAGES > 7
    if (g >= 7 * store_layers) return texelFetch(store[7], ivec3(xy, g - 7 * store_layers), 0);
#endif
#if VL_STORE_PAGES > 6
    if (g >= 6 * store_layers) return texelFetch(store[6], ivec3(xy, g - 6 * store_layers), 0);
#endif
#if VL_STORE_PAGES > 5
    if (g >= 5 * store_layers) return texelFetch(store[5], ivec3(xy, g - 5 * store_layers), 0);
#endif
#if VL_STORE_PAGES > 4
    if (g >= 4 * store_layers) return texelFetch(store[4], ivec3(xy, g - 4 * store_layers), 0);
#endif
#if VL_STORE_PAGES > 3
    if (g >= 3 * store_layers) return texelFetch(store[3], ivec3(xy, g - 3 * store_layers), 0);
#endif
#if VL_STORE_PAGES > 2
    if (g >= 2 * store_layers) return texelFetch(store[2], ivec3(xy, g - 2 * store_layers), 0);
#endif
    if (g >= store_layers) return texelFetch(store[1], ivec3(xy, g - store_layers), 0);
    return texelFetch(store[0], ivec3(xy, g), 0);
#endif
}
// value offset of row `row` of the block at base, stride values a row (offset < stride)
vec4 store_value(ivec2 base, int row, int stride, int offset) {
    return store_fetch(store_step(store_start(base, row, stride), offset));
}
#endif
