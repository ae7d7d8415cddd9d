"""The batched bounded NNLS against scipy's NNLS and a brute-force check of bounds."""

import numpy as np
import pytest
from scipy.optimize import lsq_linear, nnls

from fitting.nnls import solve_many


@pytest.mark.parametrize("n", [1, 2, 5, 9, 17])
def test_matches_scipy_nnls_without_caps(rng, n):
    problems = 40
    A = rng.normal(size=(problems, 3 * n + 4, n))
    b = rng.normal(size=(problems, 3 * n + 4)) + 0.5
    G = np.einsum("pdi,pdj->pij", A, A)
    h = np.einsum("pdi,pd->pi", A, b)
    x = solve_many(G, h, np.full((problems, n), np.inf), np.zeros((problems, n)))
    for p in range(problems):
        expected, _ = nnls(A[p], b[p])
        assert np.sum((A[p] @ x[p] - b[p]) ** 2) <= np.sum((A[p] @ expected - b[p]) ** 2) * (1 + 1e-9) + 1e-12
        np.testing.assert_allclose(x[p], expected, atol=1e-7 * max(1.0, np.abs(expected).max()))


def test_caps_match_a_bounded_solver(rng):
    problems, n = 30, 6
    A = np.abs(rng.normal(size=(problems, 20, n)))
    b = 5.0 * np.abs(rng.normal(size=(problems, 20)))
    cap = np.full((problems, n), 0.4)
    G = np.einsum("pdi,pdj->pij", A, A)
    h = np.einsum("pdi,pd->pi", A, b)
    x = solve_many(G, h, cap, np.zeros((problems, n)))
    assert (x >= 0).all() and (x <= 0.4 + 1e-12).all()
    for p in range(problems):
        ref = lsq_linear(A[p], b[p], bounds=(0, 0.4), method="bvls").x
        ours, theirs = np.sum((A[p] @ x[p] - b[p]) ** 2), np.sum((A[p] @ ref - b[p]) ** 2)
        assert ours <= theirs * (1 + 1e-6) + 1e-12


def test_degenerate_problems_give_finite_answers():
    # a zero column (a light that never shows), duplicate columns, all-zero data
    A = np.array([[1.0, 0.0, 2.0, 2.0], [1.0, 0.0, 1.0, 1.0], [1.0, 0.0, 0.0, 0.0]])
    for b in (np.array([3.0, 2.0, 1.0]), np.zeros(3), np.array([1e8, 0.0, 1e8])):
        G, h = A.T @ A, A.T @ b
        x = solve_many(G[None], h[None], np.full((1, 4), np.inf), np.zeros((1, 4)))[0]
        assert np.isfinite(x).all() and (x >= 0).all()
        expected, _ = nnls(A, b)
        assert np.sum((A @ x - b) ** 2) <= np.sum((A @ expected - b) ** 2) + 1e-9 * max(1.0, b @ b)
