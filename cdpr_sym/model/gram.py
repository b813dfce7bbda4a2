"""The determinant of a Gram matrix as the product of its LDL^T pivots, in CasADi.

A symmetric positive semi-definite G (n x n) factors as G = L D L^T with L unit lower
triangular and D = diag(d_1, ..., d_n) >= 0, so det G = d_1 d_2 ... d_n. Elimination takes
about n^3 / 3 multiply-adds; CasADi's ``det`` expands by minors instead (about 2,000
operations for n = 6; the shorter code only up to n = 3). The factorisation here is
branch-free (straight-line C) and keeps NaN: a non-finite entry gives a NaN determinant,
never a finite one.
"""

from __future__ import annotations

import casadi as ca

#: Floor added to every pivot before dividing by it, relative to trace G. A pivot that
#: rounding leaves at (or clamps to) zero then scales the rest of the elimination by at most
#: (rounding error)^2 / floor, about 1e-2 trace G, instead of dividing by zero; a pivot
#: above 1e-13 trace G is divided by unchanged (the floor is below its last bit).
PIVOT_FLOOR = 1e-30
#: Absolute part of the floor, in the unit of G's diagonal: keeps G = 0 from 0 / 0.
PIVOT_FLOOR_ABSOLUTE = 1e-300


def ldl_pivots(G: ca.SX) -> list[ca.SX]:
    """The pivots d_1, ..., d_n of G = L D L^T for a symmetric positive semi-definite G.

    Parameters
    ----------
    G : ca.SX, shape (n, n)
        Symmetric positive semi-definite; only its lower triangle is read. Any unit (the
        pivots carry the unit of G's diagonal).

    Returns
    -------
    list of ca.SX
        n scalar pivots, each >= 0 (rounding that leaves one negative is clamped to 0), or
        NaN where an entry of G is NaN.
    """
    n = G.shape[0]
    floor = PIVOT_FLOOR * ca.trace(G) + PIVOT_FLOOR_ABSOLUTE
    lower = [[G[i, j] for j in range(i + 1)] for i in range(n)]
    pivots = []
    for k in range(n):
        pivot = _clamped(lower[k][k])
        pivots.append(pivot)
        inverse = 1.0 / (pivot + floor)
        for i in range(k + 1, n):
            factor = lower[i][k] * inverse
            for j in range(k + 1, i + 1):
                lower[i][j] = lower[i][j] - factor * lower[j][k]
    return pivots


#: Up to this size CasADi's expansion by minors is the shorter code (25 operations against
#: 38 for n = 3; 78 against 63 for n = 4).
LARGEST_BY_MINORS = 3


def gram_determinant(G: ca.SX) -> ca.SX:
    """det G >= 0 for a symmetric positive semi-definite G (n x n), by its LDL^T pivots
    (expanded by minors up to :data:`LARGEST_BY_MINORS`, and clamped at 0).

    Parameters
    ----------
    G : ca.SX, shape (n, n)
        Symmetric positive semi-definite (both triangles filled, as from
        :func:`weighted_gram`).

    Returns
    -------
    ca.SX
        The determinant, in the unit of G's diagonal to the n-th power; exactly 0 where a
        pivot vanishes, NaN where an entry of G is NaN.
    """
    if G.shape[0] <= LARGEST_BY_MINORS:
        return _clamped(ca.det(G))
    pivots = ldl_pivots(G)
    product = pivots[0]
    for pivot in pivots[1:]:
        product = product * pivot
    return product


def weighted_gram(A: ca.SX, weights: list[ca.SX] | None = None) -> ca.SX:
    """A diag(weights) A^T, shape (n, n), for A of shape (n, m).

    Parameters
    ----------
    A : ca.SX, shape (n, m)
    weights : list of ca.SX, optional
        m scalars, one per column of A; all 1 when omitted.

    Returns
    -------
    ca.SX
        The symmetric Gram matrix, from n (n + 1) / 2 dot products instead of n^2.
    """
    n, m = A.shape
    scaled = A if weights is None else ca.horzcat(*[A[:, i] * weights[i] for i in range(m)])
    G = ca.SX.zeros(n, n)
    for i in range(n):
        for j in range(i + 1):
            G[i, j] = G[j, i] = ca.dot(scaled[i, :], A[j, :])
    return G


def _clamped(value: ca.SX) -> ca.SX:
    """max(value, 0) that keeps NaN (fmax(NaN, 0) is 0 in C): exact, no branch."""
    return 0.5 * (value + ca.fabs(value))
