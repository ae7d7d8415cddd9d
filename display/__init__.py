"""The display stage: rendering, the walkthrough, comparisons, export and the ``vlights``
dispatcher (docs/layout.md).

display defines no numba kernel: the kernels it runs come from radiosity and fitting, whose
``__init__`` key numba's cache on every source file a kernel may inline
(radiosity/jit_cache.py; tests/radiosity/test_jit_cache.py checks every cached kernel).
Nothing is imported here, so that ``vlights`` sets its signal handlers before numba loads.
"""
