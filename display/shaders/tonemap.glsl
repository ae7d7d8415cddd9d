// Linear radiance to display values in [0, 1]: exposure, clip to [0, 1], sRGB. The same
// as display.renderer.tonemap (numpy), which then rounds to 8 bits; tested against it.
vec3 tonemap(vec3 radiance, float exposure) {
    vec3 x = clamp(radiance * exposure, 0.0, 1.0);
    vec3 srgb = mix(12.92 * x, 1.055 * pow(x, vec3(1.0 / 2.4)) - 0.055, step(0.0031308, x));
    return clamp(srgb, 0.0, 1.0);
}
