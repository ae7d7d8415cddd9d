// What the fitted programs interpolate for the fragments: outputs where VL_OUT is
// defined (the vertex or geometry stage), inputs otherwise (the fragment stage). With
// VL_TRIANGLE, also the triangle's three vertex ids (flat) and the barycentrics: what a
// fragment needs to blend per-vertex values of a texture (per-light coefficients, the
// emitters' visibility); the renderer's geometry shader or the page's vertices give them.
#ifdef VL_OUT
#define VL_VARYING centroid out
#define VL_FLAT flat out
#else
#define VL_VARYING centroid in
#define VL_FLAT flat in
#endif
VL_VARYING vec3 v_position;
VL_VARYING vec3 v_normal;
VL_VARYING vec3 v_emitted;
VL_VARYING vec3 v_specular;
VL_VARYING vec3 v_probe;
#ifdef VL_TEXTURED
VL_VARYING vec2 v_uv;
VL_VARYING vec3 v_irradiance;
#endif
#ifdef VL_TRIANGLE
VL_VARYING vec3 v_bary;
VL_FLAT ivec3 v_vertices;
#endif
