"""The radiosity stage: scenes, light transport and the solution file (docs/layout.md)."""

from radiosity import jit_cache

jit_cache.install()  # before any kernel is decorated: numba's cache keyed on every file a kernel may inline
