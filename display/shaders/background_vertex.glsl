// One triangle over the viewport at the far plane: depth 1, or 0 with VL_REVERSED_Z (the
// renderer's and the page's reversed depth: near at 1, an infinite far plane at 0). Drawn
// after the objects with the depth test "far or equal" ("<=", reversed ">="), it fills
// only the pixels no object covers.
void main() {
#ifdef VL_REVERSED_Z
    const float far_z = 0.0;
#else
    const float far_z = 1.0;
#endif
    gl_Position = vec4(vec2((gl_VertexID << 1) & 2, gl_VertexID & 2) * 2.0 - 1.0, far_z, 1.0);
}
