// A triangle's back (back_fragment.glsl): its position alone (and a masked object's uv).
uniform mat4 mvp;
#include "clip.glsl"
in vec3 in_position;
#ifdef VL_CUTOUT
in vec2 in_uv;
centroid out vec2 v_uv;
#endif
void main() {
#ifdef VL_CUTOUT
    v_uv = in_uv;
#endif
    gl_Position = mvp * vec4(in_position, 1.0);
    VL_CLIP_VERTEX(in_position);
}
