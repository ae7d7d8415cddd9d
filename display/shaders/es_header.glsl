// Prepended to every stage on the web page (WebGL2, GLSL ES 3.00; three.js writes the
// #version line): precisions, and VL_TRIANGLE (the page's vertices carry the triangle's
// vertex ids and barycentrics). The desktop header (display.glsl.DESKTOP) is #version 330.
precision highp float;
precision highp int;
precision highp sampler2D;
#define VL_TRIANGLE
