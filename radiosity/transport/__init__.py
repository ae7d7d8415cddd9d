"""Light transport: the quality presets, the solver's orchestration (``solve``),
the one Embree wrapper, density estimation and the numba kernels (random numbers,
photons, gather). Internal to the radiosity stage (the demo also uses ``solve``)."""
