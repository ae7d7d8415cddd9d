"""Small bounded non-negative least-squares problems, many at once, in numba.

Per-light specular coefficients make each vertex's coefficients (emitted and one
specular per light, per channel) the solution of a small least-squares problem with
bounds 0 <= x <= cap. The fitter solves thousands of them in every objective
evaluation, so they are solved on their normal equations (G = A^T W A, h = A^T W b,
a few dozen unknowns at most) by an active-set method (Lawson-Hanson extended to
upper bounds), in parallel over problems.

``solve_gram(G, h, cap, x)``: min 1/2 x^T G x - h^T x subject to 0 <= x <= cap, for
one problem; ``solve_many`` over a batch (parallel).
"""

from __future__ import annotations

import numba
import numpy as np

from radiosity import jit_cache  # noqa: F401 (numba's cache keyed on every source a kernel inlines)

__all__ = ["solve_gram", "solve_many"]

_MAX_OUTER = 200


@numba.njit(cache=True, nogil=True)
def _solve_free(G, h, x, state, n):
    """The unconstrained minimiser over the free variables (state 0) with the bound
    ones (state 1: at 0, state 2: at cap) held at their values in x; Cholesky with a
    tiny ridge for rank-deficient sets. Returns z (bound entries copied from x)."""
    idx = np.empty(n, np.int64)
    m = 0
    for i in range(n):
        if state[i] == 0:
            idx[m] = i
            m += 1
    z = x.copy()
    if m == 0:
        return z
    A = np.empty((m, m))
    b = np.empty(m)
    scale = 0.0
    for a in range(m):
        scale = max(scale, G[idx[a], idx[a]])
    ridge = 1e-12 * scale if scale > 0.0 else 1e-300
    for a in range(m):
        r = h[idx[a]]
        for k in range(n):
            if state[k] != 0:
                r -= G[idx[a], k] * x[k]
        b[a] = r
        for c in range(m):
            A[a, c] = G[idx[a], idx[c]]
        A[a, a] += ridge
    L = np.zeros((m, m))
    for i in range(m):
        for j in range(i + 1):
            s = A[i, j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            if i == j:
                L[i, i] = np.sqrt(s) if s > 0.0 else np.sqrt(ridge)
            else:
                L[i, j] = s / L[j, j]
    y = np.empty(m)
    for i in range(m):
        s = b[i]
        for k in range(i):
            s -= L[i, k] * y[k]
        y[i] = s / L[i, i]
    sol = np.empty(m)
    for i in range(m - 1, -1, -1):
        s = y[i]
        for k in range(i + 1, m):
            s -= L[k, i] * sol[k]
        sol[i] = s / L[i, i]
    for a in range(m):
        z[idx[a]] = sol[a]
    return z


@numba.njit(cache=True, nogil=True)
def solve_gram(G, h, cap, x):
    """min 1/2 x^T G x - h^T x, 0 <= x <= cap (cap[i] = inf: no upper bound); writes x.

    A primal active-set method for the box (Lawson-Hanson extended to upper bounds):
    start with every variable at 0; free the bound variable whose gradient most
    violates optimality; solve for the free ones; if that leaves the box, step to the
    box's edge and bind the variables that reach it; repeat until no bound variable
    violates optimality."""
    n = h.shape[0]
    state = np.ones(n, np.int64)  # 0 free, 1 at zero, 2 at cap
    for i in range(n):
        x[i] = 0.0
        if cap[i] <= 0.0:
            state[i] = 1
    scale = 0.0
    for i in range(n):
        scale = max(scale, abs(h[i]))
    tol = 1e-13 * (scale if scale > 0.0 else 1.0)
    for _ in range(_MAX_OUTER):
        best, j = tol, -1
        for i in range(n):
            if state[i] == 0:
                continue
            g = h[i]  # minus the gradient
            for k in range(n):
                g -= G[i, k] * x[k]
            violation = g if state[i] == 1 else -g
            if state[i] == 1 and cap[i] <= 0.0:
                violation = 0.0
            if violation > best:
                best, j = violation, i
        if j < 0:
            break
        state[j] = 0
        for _inner in range(3 * n + 3):
            z = _solve_free(G, h, x, state, n)
            alpha = 1.0
            hit = -1
            for i in range(n):
                if state[i] != 0:
                    continue
                if z[i] < 0.0:
                    step = x[i] / (x[i] - z[i]) if x[i] - z[i] > 0.0 else 0.0
                    if step < alpha:
                        alpha, hit = step, i
                elif z[i] > cap[i]:
                    step = (cap[i] - x[i]) / (z[i] - x[i]) if z[i] - x[i] > 0.0 else 0.0
                    if step < alpha:
                        alpha, hit = step, i
            for i in range(n):
                if state[i] == 0:
                    x[i] = x[i] + alpha * (z[i] - x[i])
            if hit < 0:
                break
            # bind every free variable now at (or past) a bound
            for i in range(n):
                if state[i] == 0:
                    if x[i] <= 0.0 or i == hit and z[i] < 0.0:
                        x[i] = 0.0
                        state[i] = 1
                    elif x[i] >= cap[i] or i == hit and z[i] > cap[i]:
                        x[i] = cap[i]
                        state[i] = 2
    return x


@numba.njit(cache=True, nogil=True, parallel=True)
def solve_many(G, h, cap, x):
    """A batch: G (P, n, n), h (P, n), cap (P, n), x (P, n) written."""
    for p in numba.prange(h.shape[0]):
        solve_gram(G[p], h[p], cap[p], x[p])
    return x
