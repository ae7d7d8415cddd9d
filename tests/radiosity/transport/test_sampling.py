"""Small numba helpers of radiosity.transport.sampling that both the photon bounce and
the gather continuation use."""

import numpy as np
import pytest

from radiosity.transport import sampling


@pytest.mark.parametrize(
    "value, reference, survive",
    [
        ((0.2, 0.5, 0.1), 1.0, 0.5),  # a gather path's throughput (reference 1)
        ((0.2, 0.5, 0.1), 0.25, 1.0),  # a photon that gained power keeps it all
        ((0.2, 0.5, 0.1), 2.0, 0.25),  # a photon that lost power: survives with the ratio
        ((0.0, 0.0, 0.0), 1.0, 0.0),  # nothing left: dies
        ((0.2, 0.5, 0.1), 0.0, 0.0),  # nothing before: dies
    ],
)
def test_roulette_survival_and_weight(value, reference, survive):
    for u in (0.0, 0.2499, 0.4999, 0.5, 0.9999):
        survives, carried = sampling.roulette(value, reference, u)
        assert survives == (u < survive)
        if survives:
            assert carried == pytest.approx(tuple(v / survive for v in value), rel=1e-15)


def test_roulette_is_unbiased_and_keeps_weights_near_the_reference(rng):
    value, reference = (0.03, 0.12, 0.06), 0.4
    total = np.zeros(3)
    n = 20_000
    for u in rng.random(n):
        survives, carried = sampling.roulette(value, reference, u)
        if survives:
            total += carried
            assert max(carried) == pytest.approx(reference)
    assert np.allclose(total / n, value, rtol=0.03)


def test_every_random_stream_is_named_once_with_a_number_of_its_own():
    """The streams' table (``radiosity.transport.rng.STREAMS``): distinct numbers, so no
    two kinds of sample draw the same numbers; the gather's four kept the numbers they
    had as STREAM_GATHER + 0 .. 3 (every seed's results as before), and no kernel
    module counts streams by adding to one."""
    import pathlib

    from radiosity.transport import rng

    assert len(set(rng.STREAMS.values())) == len(rng.STREAMS) >= 9
    assert [rng.STREAM_GATHER + k for k in range(4)] == [rng.STREAM_GATHER, rng.STREAM_LOBE, rng.STREAM_GATHER_LIGHT,
                                                         rng.STREAM_GATHER_DELTA]
    source = pathlib.Path(rng.__file__).parent
    for path in source.glob("*.py"):
        assert "STREAM_GATHER +" not in path.read_text(), path.name
