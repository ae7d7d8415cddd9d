// A glass object (glass.glsl), either face: its colour, premultiplied, and what it lets
// through of the framebuffer behind (1 - alpha) where it is drawn blended.
uniform vec3 eye;
in vec3 v_position;
in vec3 v_normal;
out vec4 f_colour;
#include "glass.glsl"
void main() {
    f_colour = glass_colour(v_position, normalize(v_normal), normalize(eye - v_position));
}
