// An object's opacity mask (radiosity.physics.textures: a leaf's cut-out): the fragment is
// discarded where the mask reads below the cut-off, as the solver's and the path tracer's
// rays pass through there (radiosity.transport.embree's filter). Read bilinear at the base
// level, as they read it: a mipmapped mask would thin the leaves with distance.
// Compiled in under #define VL_CUTOUT (the programs of masked objects).
// The renderer's mask is a texture of its own (one channel); the page's is its image's
// alpha (glTF's alphaMode MASK: #define VL_CUTOUT_ALPHA).
#ifdef VL_CUTOUT
uniform sampler2D cutout_texture;
const float CUTOUT_CUTOFF = 0.5;
void cutout(vec2 uv) {
#ifdef VL_CUTOUT_ALPHA
    if (textureLod(cutout_texture, uv, 0.0).a < CUTOUT_CUTOFF) discard;
#else
    if (textureLod(cutout_texture, uv, 0.0).r < CUTOUT_CUTOFF) discard;
#endif
}
#endif
