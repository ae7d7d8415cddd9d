"""Drawing from a tabulated distribution: the index a uniform number falls on in a
cumulative table (the kernels' environment map, emitter triangles and delta lights).
"""

from __future__ import annotations

import numba

from radiosity import jit_cache  # noqa: F401 (numba's cache keyed on every source a kernel inlines)


@numba.njit(cache=True, nogil=True, inline="always")
def search_cdf(cdf, u):
    """np.searchsorted(cdf, u, side="right") by hand: numba's, for one number, allocates."""
    lo, hi = 0, len(cdf)
    while lo < hi:
        mid = (lo + hi) >> 1
        if cdf[mid] <= u:
            lo = mid + 1
        else:
            hi = mid
    return lo
