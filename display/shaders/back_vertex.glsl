// A triangle's back (back_fragment.glsl): its position alone.
uniform mat4 mvp;
#include "clip.glsl"
in vec3 in_position;
void main() {
    gl_Position = mvp * vec4(in_position, 1.0);
    VL_CLIP_VERTEX(in_position);
}
