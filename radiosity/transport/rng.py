"""The solver's and the path tracer's random numbers: a counter-based hash of (seed,
stream, item, dimension), so a result depends on the seed and each item's index
alone, never on how work is split into batches, threads or machines.

Streams, every one named here (``STREAMS``: distinct numbers, so no two kinds of sample
share their numbers; the numbers are the ones every seed's results were made with):

    STREAM_EMIT          photon emission
    STREAM_BOUNCE        photon scattering (``PHOTON_DIMS_PER_BOUNCE`` dimensions a bounce)
    STREAM_LIGHT         a gather vertex's light samples
    STREAM_GATHER        its gather rays
    STREAM_LOBE          a gather path's continuation through a glossy hit's lobe
    STREAM_GATHER_LIGHT  the light sample at a glossy hit of a gather path
    STREAM_GATHER_DELTA  the delta light's sample there
    STREAM_CAMERA        the path tracer's position in the pixel
    STREAM_PATH          the path tracer's paths (``pathtrace.DIMS_PER_BOUNCE`` a bounce)
"""

from __future__ import annotations

import numba
import numpy as np

from radiosity import jit_cache  # noqa: F401 (numba's cache keyed on every source a kernel inlines)

STREAM_EMIT, STREAM_BOUNCE, STREAM_LIGHT, STREAM_GATHER = 1, 2, 3, 4
STREAM_LOBE, STREAM_GATHER_LIGHT, STREAM_GATHER_DELTA = 5, 6, 7
STREAM_CAMERA, STREAM_PATH = 11, 12
STREAMS = {name: value for name, value in globals().items() if name.startswith("STREAM_")}
PHOTON_DIMS_PER_BOUNCE = 8  # a photon's numbers at each bounce: the scatter (3), roulette (1), the rest spare

_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_INV_2_53 = 1.0 / 9007199254740992.0


@numba.njit(inline="always")
def _mix(z):
    z = (z ^ (z >> np.uint64(30))) * _M1
    z = (z ^ (z >> np.uint64(27))) * _M2
    return z ^ (z >> np.uint64(31))


@numba.njit(cache=True, nogil=True)
def rand(seed, stream, item, dim):
    """A uniform number in [0, 1) determined by (seed, stream, item, dim) alone."""
    z = _mix(np.uint64(seed) * _GOLDEN + np.uint64(stream))
    z = _mix(z ^ (np.uint64(item) * _GOLDEN))
    z = _mix(z + np.uint64(dim) * _M1)
    return float(z >> np.uint64(11)) * _INV_2_53
