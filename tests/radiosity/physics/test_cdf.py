"""The kernels' hand-written CDF search is numpy's searchsorted(side="right")."""

import numba
import numpy as np

from radiosity.physics.cdf import search_cdf


@numba.njit
def _search_all(cdf, us):
    out = np.empty(len(us), np.int64)
    for i in range(len(us)):
        out[i] = search_cdf(cdf, us[i])
    return out


def test_search_cdf_equals_searchsorted_right(rng):
    for n in (1, 2, 3, 17, 1000):
        cdf = np.cumsum(rng.uniform(0, 1, n) * (rng.random(n) > 0.3))  # with flat runs (zero-power triangles)
        cdf /= cdf[-1] if cdf[-1] > 0 else 1.0
        us = np.concatenate([rng.random(5000), cdf, np.nextafter(cdf, 0), [0.0, np.nextafter(1.0, 0), 1.0]])
        assert np.array_equal(_search_all(cdf, us), np.searchsorted(cdf, us, side="right"))
