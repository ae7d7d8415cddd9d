// A near mirror's surface (near_fragment.glsl): its position, normal, base colour and,
// for a textured one, its uv and irradiance.
uniform mat4 mvp;
in vec3 in_position;
in vec3 in_normal;
in vec3 in_emitted;
in vec2 in_uv;
in vec3 in_irradiance;
out vec3 v_position;
out vec3 v_normal;
out vec3 v_base;
out vec2 v_uv;
out vec3 v_irradiance;
void main() {
    gl_Position = mvp * vec4(in_position, 1.0);
    v_position = in_position;
    v_normal = in_normal;
    v_base = in_emitted;
    v_uv = in_uv;
    v_irradiance = in_irradiance;
}
