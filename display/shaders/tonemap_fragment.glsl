// The picture on the screen: each pixel the tone-mapped texel of the HDR image of the
// same size (the renderer's float framebuffer, the page's render target).
uniform sampler2D hdr;
uniform float exposure;
out vec4 f_colour;
#include "tonemap.glsl"
void main() {
    f_colour = vec4(tonemap(texelFetch(hdr, ivec2(gl_FragCoord.xy), 0).rgb, exposure), 1.0);
}
