"""The radiosity stage: scenes, light transport and the solution file (docs/layout.md).

Importing it loads nothing: a command that only parses its flags starts without numba.
Every module that decorates a numba kernel imports ``radiosity.jit_cache`` first, which
keys numba's on-disk cache on every source file a kernel may inline (a test checks
that each such module does).
"""
