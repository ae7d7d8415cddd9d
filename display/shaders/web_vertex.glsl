// The web page's vertex stage (three.js RawShaderMaterial: its matrix uniforms and
// attribute names). Objects with per-vertex texture values are drawn with one vertex per
// triangle corner carrying the triangle's vertex ids and the corner's barycentrics: the
// fragments get what the renderer's geometry shader hands them (pixel_geometry.glsl).
// Under VL_TEXTURED (a textured object's program) also its uv and irradiance: glTF's uv,
// whose v runs down the image, which the page uploads top row first (t = 0), so that
// texture(diffuse_texture, v_uv) reads what the renderer's does with v up.
uniform mat4 modelViewMatrix;
uniform mat4 projectionMatrix;
in vec3 position;
in vec3 normal;
in vec3 emitted;
in vec3 specular;
in vec3 probe;      // the probe's weight (0 without a probe)
in vec3 vertices;   // per light or highlight: the triangle's three vertex ids (else 0)
in vec3 bary;       // per light or highlight: this corner's barycentrics (else 0)
#ifdef VL_TEXTURED
in vec2 uv;         // glTF's TEXCOORD_0
in vec3 irradiance; // _IRRADIANCE
#endif
#define VL_OUT
#include "fitted_varyings.glsl"
void main() {
    gl_Position = projectionMatrix * modelViewMatrix * vec4(position, 1.0);
    v_position = position;
    v_normal = normal;
    v_emitted = emitted;
    v_specular = specular;
    v_probe = probe;
    v_bary = bary;
    v_vertices = ivec3(vertices);
#ifdef VL_TEXTURED
    v_uv = uv;
    v_irradiance = irradiance;
#endif
}
