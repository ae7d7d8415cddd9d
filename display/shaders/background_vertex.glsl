// One triangle over the viewport at the far plane (depth 1): drawn after the objects
// with the depth test "<=", it fills only the pixels no object covers.
void main() {
    gl_Position = vec4(vec2((gl_VertexID << 1) & 2, gl_VertexID & 2) * 2.0 - 1.0, 1.0, 1.0);
}
