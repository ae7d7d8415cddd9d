// A flat mirror's view of the scene (display.mirror): what lies behind the mirror's plane
// is clipped away, on the desktop alone (VL_CLIP; the page's GLSL ES has no clip
// distances). clip_plane = (n, -n . p): a point x is kept where n . x - n . p >= 0.
#ifdef VL_CLIP
uniform vec4 clip_plane;
#define VL_CLIP_VERTEX(p) gl_ClipDistance[0] = dot(vec4(p, 1.0), clip_plane)
#define VL_CLIP_PASS(i) gl_ClipDistance[0] = gl_in[i].gl_ClipDistance[0]
#else
#define VL_CLIP_VERTEX(p)
#define VL_CLIP_PASS(i)
#endif
