"""The run-time policies every stage applies the same way: ``presets`` (the one table
of every speed/accuracy knob, ``--quality``), ``limits`` (the seed's range, an
exposure's, the memory still free under cgroup limits), ``cluster`` (reaching Dask).

Part of the radiosity stage's shared core, with ``radiosity.files`` and
``radiosity.physics``: what the other stages may import (the README's stage rule).
Nothing here imports numba, the scene loaders or the light transport. Import each name
from its module; this package's own import loads nothing.
"""
