// A fitted object's vertex attributes (display.renderer._Object's buffers).
in vec3 in_position;
in vec3 in_normal;
in vec3 in_emitted;
in vec3 in_specular;
in vec3 in_probe;
#ifdef VL_TEXTURED
in vec2 in_uv;
in vec3 in_irradiance;
#endif
