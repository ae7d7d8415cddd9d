// A textured object's diffuse term (radiosity.physics.textures): kd * texture(uv) / pi * E,
// the texture read per pixel, uv and the irradiance E interpolated from the vertices.
// Compiled in under #define VL_TEXTURED (the programs of textured objects); the image is
// uploaded bottom row first, so that t = v (v up, as the files' uvs) and GL's bilinear,
// repeating filter is radiosity.physics.textures.lookup's.
#ifdef VL_TEXTURED
uniform sampler2D diffuse_texture;
uniform vec3 texture_kd;
vec3 textured_term(vec2 uv, vec3 irradiance) {
    return texture_kd * texture(diffuse_texture, uv).rgb * irradiance * 0.3183098861837907;
}
#endif
