"""The fast edge and position tables of ``geometry`` give exactly what the numpy
row-unique calls they replace gave (``np.unique(..., axis=0)``), so refinement is
unchanged bit for bit."""

import numpy as np
import pytest

from radiosity.scene import geometry
from radiosity.scene.loaders import load_scene


@pytest.mark.parametrize("dtype", [np.int64, np.int32])
@pytest.mark.parametrize("n", [0, 1, 7, 5000])
def test_unique_pairs_is_np_unique_of_rows(rng, dtype, n):
    pairs = np.sort(rng.integers(0, max(n // 3, 1), (n, 2)), axis=1).astype(dtype)
    expected, inverse = np.unique(pairs, axis=0, return_inverse=True)
    got, got_inverse = geometry.unique_pairs(pairs, return_inverse=True)
    assert got.dtype == expected.dtype and np.array_equal(got, expected)
    assert np.array_equal(got_inverse, inverse.reshape(-1))
    assert np.array_equal(geometry.unique_pairs(pairs), expected)


def test_unique_edges_of_a_mesh(rng):
    faces = rng.integers(0, 300, (1000, 3))
    expected = np.unique(np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1), axis=0)
    assert np.array_equal(geometry.unique_edges(faces), expected)


def test_position_labels_are_np_unique_inverse(rng):
    points = rng.integers(0, 4, (3000, 3)) * 0.5
    points[rng.random(3000) < 0.2] *= -1  # -0.0 and 0.0 are one position
    _, inverse = np.unique(points, axis=0, return_inverse=True)
    assert np.array_equal(geometry.position_labels(points), inverse.reshape(-1))
    for o in load_scene("cornell-teapot").refined(60.0).objects:  # crease copies share labels
        _, inverse = np.unique(o.positions, axis=0, return_inverse=True)
        assert np.array_equal(geometry.position_labels(o.positions), inverse.reshape(-1))
    assert len(geometry.position_labels(np.zeros((0, 3)))) == 0
