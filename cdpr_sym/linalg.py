"""Gram matrices in CasADi: their determinant and linear solves by LDL^T, branch-free.

A symmetric positive semi-definite G (n x n) factors as G = L D L^T with L unit lower
triangular and D = diag(d_1, ..., d_n) >= 0, so det G = d_1 d_2 ... d_n, and G x = b is two
triangular solves and a division. Elimination takes about n^3 / 3 multiply-adds. CasADi's
``det`` expands by minors instead (for n = 6 about 2,000 operations as written, 341 once
common subexpressions are shared, against 145 here) and its ``solve`` of a symbolic matrix
is a QR factorisation. The factorisation here is straight-line C and keeps NaN: a
non-finite entry gives NaN, never a finite number.

The bottom of the package (beside the robot description): the model's singularity measure
and the tension distribution both use it.
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


def pseudo_inverse_times(W: ca.SX, force: ca.SX) -> ca.SX:
    """W^+ ``force``: W^T (W W^T)^-1 f (the least-norm tension, m >= n, W of full row rank),
    or with fewer cables than coordinates (W of full column rank) (W^T W)^-1 W^T f, the
    tension whose force is nearest f (N)."""
    n, m = W.shape
    if m < n:
        return ca.solve(ca.densify(W.T @ W), W.T @ force)
    return W.T @ ca.solve(W @ W.T, force)


def ldl_factors(G: ca.SX) -> tuple[list[list[ca.SX]], list[ca.SX], ca.SX]:
    """The factors of G = L D L^T for a symmetric positive semi-definite G (n x n).

    Parameters
    ----------
    G : ca.SX, shape (n, n)
        Symmetric positive semi-definite; only its lower triangle is read. Any unit (the
        pivots carry the unit of G's diagonal).

    Returns
    -------
    factors : list of list of ca.SX
        Row i holds L's strict lower triangle, L[i, 0..i-1].
    pivots : list of ca.SX
        d_1, ..., d_n, each >= 0 (rounding that leaves one negative is clamped to 0), or
        NaN where an entry of G is NaN.
    floor : ca.SX
        What the elimination added to every pivot before dividing by it
        (:data:`PIVOT_FLOOR` trace G + :data:`PIVOT_FLOOR_ABSOLUTE`): a singular G gives
        finite factors instead of a division by zero.
    """
    n = G.shape[0]
    floor = PIVOT_FLOOR * ca.trace(G) + PIVOT_FLOOR_ABSOLUTE
    lower = [[G[i, j] for j in range(i + 1)] for i in range(n)]
    factors: list[list[ca.SX]] = [[] for _ in range(n)]
    pivots = []
    for k in range(n):
        pivots.append(_clamped(lower[k][k]))
        inverse = 1.0 / (pivots[k] + floor)
        for i in range(k + 1, n):
            factors[i].append(lower[i][k] * inverse)
            for j in range(k + 1, i + 1):
                lower[i][j] = lower[i][j] - factors[i][k] * lower[j][k]
    return factors, pivots, floor


def ldl_pivots(G: ca.SX) -> list[ca.SX]:
    """The pivots d_1, ..., d_n of G = L D L^T (see :func:`ldl_factors`)."""
    return ldl_factors(G)[1]


def ldl_solve(G: ca.SX, b: ca.SX) -> ca.SX:
    """x with G x = b for a symmetric positive definite G (n x n) and b (n,), by LDL^T.

    Parameters
    ----------
    G : ca.SX, shape (n, n)
        Symmetric positive definite (lower triangle read); its pivots are floored as in
        :func:`ldl_factors`, so a singular G returns finite numbers that do not solve it
        (callers that can meet one check the residual).
    b : ca.SX, shape (n,)
        Right-hand side, any unit.

    Returns
    -------
    ca.SX, shape (n,)
        The solution, in b's unit over G's.
    """
    n = G.shape[0]
    factors, pivots, floor = ldl_factors(G)
    y = [b[i] for i in range(n)]
    for i in range(n):  # L y = b
        for j, factor in enumerate(factors[i]):
            y[i] = y[i] - factor * y[j]
    x = [y[i] / (pivots[i] + floor) for i in range(n)]
    for i in reversed(range(n)):  # L^T x = D^-1 y
        for k in range(i + 1, n):
            x[i] = x[i] - factors[k][i] * x[k]
    return ca.vertcat(*x)


#: Up to this size CasADi's expansion by minors is the shorter code (as written, 25
#: operations against 38 for n = 3 and 78 against 63 for n = 4; with shared subexpressions
#: n = 4 is about even, 60 against 63).
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
