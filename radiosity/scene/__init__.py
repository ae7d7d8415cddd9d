"""Scene input: the scene model, the loaders (TOML, OBJ/MTL, glTF, built-ins), the
teapot, mesh geometry (normals, refinement) and the materials' BRDF kernels.
Internal to the radiosity stage (the demo also uses ``load_scene``)."""
