"""The arithmetic of a Levenberg–Marquardt step, the same bytes on any CPU.

BLAS and LAPACK (``r @ r``, ``J.T @ J``, ``np.linalg.solve``) sum in an order that depends on the
CPU's kernel, so their last digits differ from machine to machine; along a flat valley of a fit,
the iterations amplify that into a different optimum (the 5th digit of a candidate's shrink).
Here the sums run in one fixed order (numba, no fastmath) and the damped normal equations are
solved by a Cholesky factorisation: they are symmetric positive definite for any damping > 0.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

Array = NDArray[np.float64]


@njit(cache=True)
def sumsq(r: Array) -> float:
    """Σ r², summed in order."""
    s = 0.0
    for v in r:
        s += v * v
    return s


@njit(cache=True)
def _normal(J: Array, r: Array) -> tuple[Array, Array]:
    """(JᵀJ, Jᵀr), summed in row order."""
    m, n = J.shape
    jtj, g = np.zeros((n, n)), np.zeros(n)
    for i in range(m):
        for a in range(n):
            g[a] += J[i, a] * r[i]
            for b in range(a + 1):
                jtj[a, b] += J[i, a] * J[i, b]
    for a in range(n):
        for b in range(a):
            jtj[b, a] = jtj[a, b]
    return jtj, g


@njit(cache=True)
def _cholesky_solve(A: Array, b: Array) -> Array:
    """x with A·x = b for a symmetric positive definite A (lower Cholesky factor, two triangular solves)."""
    n = b.size
    L = np.zeros((n, n))
    for j in range(n):
        s = A[j, j]
        for k in range(j):
            s -= L[j, k] * L[j, k]
        L[j, j] = np.sqrt(s)
        for i in range(j + 1, n):
            s = A[i, j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            L[i, j] = s / L[j, j]
    y = np.zeros(n)
    for i in range(n):
        s = b[i]
        for k in range(i):
            s -= L[i, k] * y[k]
        y[i] = s / L[i, i]
    x = np.zeros(n)
    for i in range(n - 1, -1, -1):
        s = y[i]
        for k in range(i + 1, n):
            s -= L[k, i] * x[k]
        x[i] = s / L[i, i]
    return x


@njit(cache=True)
def damped_steps(J: Array, r: Array, lams: Array) -> Array:
    """Gauss–Newton steps damped Marquardt's way, one row per λ of ``lams`` (each > 0): the solution δ of
    (JᵀJ + λ·diag(JᵀJ + 1e-12))·δ = −Jᵀr."""
    jtj, g = _normal(J, r)
    n = g.size
    out = np.zeros((lams.size, n))
    for k in range(lams.size):
        A = jtj.copy()
        for a in range(n):
            A[a, a] += lams[k] * (jtj[a, a] + 1e-12)
        out[k] = _cholesky_solve(A, -g)
    return out
