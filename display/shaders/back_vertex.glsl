// A triangle's back (back_fragment.glsl): its position alone.
uniform mat4 mvp;
in vec3 in_position;
void main() {
    gl_Position = mvp * vec4(in_position, 1.0);
}
