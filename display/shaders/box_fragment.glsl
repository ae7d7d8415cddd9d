// Supersampling's last step: pixel (x, y) of the image is the mean of the factor x factor
// block of the larger (already MSAA-resolved) image it covers.
uniform sampler2D image;
uniform int factor;
out vec4 f_colour;
void main() {
    ivec2 corner = ivec2(gl_FragCoord.xy) * factor;
    vec4 sum = vec4(0.0);
    for (int j = 0; j < factor; ++j)
        for (int i = 0; i < factor; ++i)
            sum += texelFetch(image, corner + ivec2(i, j), 0);
    f_colour = sum / float(factor * factor);
}
