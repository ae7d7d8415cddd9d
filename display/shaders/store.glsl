// The renderer's float store (display.renderer.StoreLayout): the solution's radiance grids,
// the fitted per-light coefficients and the emitters' visibility of every object, one
// RGB32F value a texel, in VL_STORE_PAGES 2D array textures ("pages", each a sampler of
// its own). Value i of the store (a count that may pass 2^31) lies in layer g = i / L at
// texel t = i % L, that is (t % store_width, t / store_width), with L = store_width *
// store_rows texels a layer, a multiple of 2^16; layer g is layer g % store_layers of
// page g / store_layers. A value is never named by i: a block of values starts at an
// address (g, t), and store_start finds a row of the block in 32-bit unsigned
// arithmetic whose every product and sum stays below 2^32.
// Compiled where the renderer defines VL_STORE_PAGES (the desktop); the web page keeps
// one 2D texture per object (lights.glsl, emitters.glsl, their #else branches).
#ifdef VL_STORE_PAGES
uniform sampler2DArray store[VL_STORE_PAGES];
uniform int store_width;
uniform int store_rows;
uniform int store_layers;   // layers a page (the last page may have fewer)
// the address of value base + row * stride: base an address, 0 <= row < 2^31,
// 1 <= stride <= 2^16 (row * stride = high * 2^16 + low, high < 2^31, low < 2^32)
ivec2 store_start(ivec2 base, int row, int stride) {
    uint layer_texels = uint(store_width) * uint(store_rows);
    uint units = layer_texels >> 16;    // L = units * 2^16
    uint high = (uint(row) >> 16) * uint(stride);
    uint low = (uint(row) & 0xFFFFu) * uint(stride);
    uint t = uint(base.y) + (high % units) * 65536u + low % layer_texels;   // < 3 L
    uint g = uint(base.x) + high / units + low / layer_texels + t / layer_texels;
    return ivec2(int(g), int(t % layer_texels));
}
// the address offset values after address at (0 <= offset <= L)
ivec2 store_step(ivec2 at, int offset) {
    uint layer_texels = uint(store_width) * uint(store_rows);
    uint t = uint(at.y) + uint(offset);
    return t < layer_texels ? ivec2(at.x, int(t)) : ivec2(at.x + 1, int(t - layer_texels));
}
// the value at an address
vec4 store_fetch(ivec2 at) {
    int page = at.x / store_layers;
    ivec3 texel = ivec3(at.y % store_width, at.y / store_width, at.x - page * store_layers);
#if VL_STORE_PAGES > 7
    if (page == 7) return texelFetch(store[7], texel, 0);
#endif
#if VL_STORE_PAGES > 6
    if (page == 6) return texelFetch(store[6], texel, 0);
#endif
#if VL_STORE_PAGES > 5
    if (page == 5) return texelFetch(store[5], texel, 0);
#endif
#if VL_STORE_PAGES > 4
    if (page == 4) return texelFetch(store[4], texel, 0);
#endif
#if VL_STORE_PAGES > 3
    if (page == 3) return texelFetch(store[3], texel, 0);
#endif
#if VL_STORE_PAGES > 2
    if (page == 2) return texelFetch(store[2], texel, 0);
#endif
#if VL_STORE_PAGES > 1
    if (page == 1) return texelFetch(store[1], texel, 0);
#endif
    return texelFetch(store[0], texel, 0);
}
// value offset of row `row` of the block at base, stride values a row (offset < stride)
vec4 store_value(ivec2 base, int row, int stride, int offset) {
    return store_fetch(store_step(store_start(base, row, stride), offset));
}
#endif
