"""Banded LU with partial pivoting for the compiled sweep of large mechanisms.

A chain's Jacobian, with its bodies in reverse Cuthill-McKee order and each
constraint's rows beside its first body, is banded: ``kl`` diagonals below the
main one, ``ku`` above. Partial pivoting keeps the lower bandwidth and widens
the upper one to ``kl + ku`` (LAPACK's ``gbtrf``), so a factorisation costs
O(n kl (kl + ku)) instead of O(n^3), and a solve O(n (2 kl + ku)).

Storage, row by row: row i of the (n, n) matrix holds its columns
``i - kl .. i + kl + ku`` at ``a[i, j - i + kl]`` (width ``2 kl + ku + 1``).
The multipliers of L stay where elimination left them, and the row swaps
are applied to the right-hand side as they come (``gbtrs``), so L is never
permuted back.

The exact 1-norm condition number needs the whole inverse, which is dense:
here it is estimated (Hager's method as refined by Higham, LAPACK's
``lacn2``/``gecon``): a lower bound on ||A^-1||_1 from at most eleven solves.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: Hager-Higham iterations at most (LAPACK's ITMAX)
_ESTIMATOR_ITERATIONS = 5


@njit(cache=True)
def band_lu(a, kl, ku, piv):
    """Factorise the banded a (n, 2 kl + ku + 1) in place; returns the sign of its
    determinant (0 if a pivot is exactly zero, NaN if one is NaN), as ``_lu``."""
    n = a.shape[0]
    sign = 1.0
    for k in range(n):
        last_row = min(n - 1, k + kl)
        last_col = min(n - 1, k + kl + ku)
        p = k
        big = abs(a[k, kl])
        for i in range(k + 1, last_row + 1):
            v = abs(a[i, k - i + kl])
            if v > big:
                big, p = v, i
        piv[k] = p
        if p != k:
            sign = -sign
            for j in range(k, last_col + 1):
                a[k, j - k + kl], a[p, j - p + kl] = a[p, j - p + kl], a[k, j - k + kl]
        pivot = a[k, kl]
        if pivot != pivot:
            return np.nan
        if pivot == 0.0:
            return 0.0
        if pivot < 0.0:
            sign = -sign
        for i in range(k + 1, last_row + 1):
            factor = a[i, k - i + kl] / pivot
            a[i, k - i + kl] = factor
            if factor != 0.0:
                for j in range(k + 1, last_col + 1):
                    a[i, j - i + kl] -= factor * a[k, j - k + kl]
    return sign


@njit(cache=True)
def band_solve(lu, kl, ku, piv, x):
    """x (n,) becomes A^-1 x, with the factors of :func:`band_lu`."""
    n = lu.shape[0]
    for k in range(n):
        p = piv[k]
        if p != k:
            x[k], x[p] = x[p], x[k]
        xk = x[k]
        if xk != 0.0:
            for i in range(k + 1, min(n - 1, k + kl) + 1):
                x[i] -= lu[i, k - i + kl] * xk
    for m in range(n - 1, -1, -1):
        xm = x[m] / lu[m, kl]
        x[m] = xm
        if xm != 0.0:
            for i in range(max(0, m - kl - ku), m):
                x[i] -= lu[i, m - i + kl] * xm


@njit(cache=True)
def band_solve_transposed(lu, kl, ku, piv, x):
    """x (n,) becomes A^-T x, with the factors of :func:`band_lu`:
    A = P_0 L_0 ... P_{n-1} L_{n-1} U, so A^-T = P_0 L_0^-T ... P_{n-1} L_{n-1}^-T U^-T."""
    n = lu.shape[0]
    for m in range(n):
        total = x[m]
        for i in range(max(0, m - kl - ku), m):
            total -= lu[i, m - i + kl] * x[i]
        x[m] = total / lu[m, kl]
    for k in range(n - 1, -1, -1):
        total = x[k]
        for i in range(k + 1, min(n - 1, k + kl) + 1):
            total -= lu[i, k - i + kl] * x[i]
        x[k] = total
        p = piv[k]
        if p != k:
            x[k], x[p] = x[p], x[k]


@njit(cache=True)
def band_norm1(a, kl, column_sums):
    """Largest column sum of |a| of the banded a (before factorising; NaN if any
    entry is NaN); ``column_sums`` (n,) is scratch."""
    n = a.shape[0]
    column_sums[:] = 0.0
    for i in range(n):
        for jj in range(a.shape[1]):
            j = jj + i - kl
            if 0 <= j < n:
                column_sums[j] += abs(a[i, jj])
    norm = -np.inf
    for j in range(n):
        if column_sums[j] != column_sums[j]:
            return np.nan
        if column_sums[j] > norm:
            norm = column_sums[j]
    return norm


@njit(cache=True)
def _sum_abs(x):
    total = 0.0
    for v in x:
        total += abs(v)
    return total


@njit(cache=True)
def _first_largest(x):
    best, at = -1.0, 0
    for i in range(len(x)):
        if abs(x[i]) > best:
            best, at = abs(x[i]), i
    return at


@njit(cache=True)
def inverse_norm1_estimate(lu, kl, ku, piv, x, signs):
    """A lower bound on ||A^-1||_1 from the factors of :func:`band_lu`, as LAPACK's
    ``dlacn2`` computes it (exact unless A^-1 is unusually structured; Higham 1988).
    ``x``, ``signs`` (n,) are scratch."""
    n = lu.shape[0]
    x[:] = 1.0 / n
    band_solve(lu, kl, ku, piv, x)
    if n == 1:
        return abs(x[0])
    estimate = _sum_abs(x)
    for i in range(n):
        signs[i] = 1.0 if x[i] >= 0.0 else -1.0
        x[i] = signs[i]
    band_solve_transposed(lu, kl, ku, piv, x)
    j = _first_largest(x)
    for _ in range(2, _ESTIMATOR_ITERATIONS + 1):
        x[:] = 0.0
        x[j] = 1.0
        band_solve(lu, kl, ku, piv, x)
        previous = estimate
        estimate = _sum_abs(x)
        same_signs = True
        for i in range(n):
            if (1.0 if x[i] >= 0.0 else -1.0) != signs[i]:
                same_signs = False
                break
        if same_signs or estimate <= previous:
            break
        for i in range(n):
            signs[i] = 1.0 if x[i] >= 0.0 else -1.0
            x[i] = signs[i]
        band_solve_transposed(lu, kl, ku, piv, x)
        last = j
        j = _first_largest(x)
        if x[last] == abs(x[j]):
            break
    # Higham's alternative: a vector of alternating signs, for matrices that fool the above
    for i in range(n):
        x[i] = (1.0 if i % 2 == 0 else -1.0) * (1.0 + i / (n - 1))
    band_solve(lu, kl, ku, piv, x)
    alternative = 2.0 * _sum_abs(x) / (3.0 * n)
    return max(estimate, alternative) if math.isfinite(alternative) else estimate
