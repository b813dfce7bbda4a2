"""Exact tension distribution when the null space of W is two-dimensional (m = n + 2).

Every tension with W tau = w is tau = tau_p + N lambda, lambda in R^2, with tau_p = W^+ w
and N an orthonormal basis of the null space of W (both from a Householder QR of W^T, see
:func:`orthogonal_split`). As tau_p is orthogonal to N, |tau|^2 = |tau_p|^2 + |lambda|^2:
the minimum-2-norm tension in the box is the point of the feasible polygon

    P = {lambda : t_min <= tau_p,i + a_i . lambda <= t_max, i = 1..m}   (a_i: row i of N)

nearest the origin. That point is the origin when tau_p is in the box. Otherwise it lies on
the line a_i . lambda = b - tau_p,i of a bound b that tau_p violates (were every constraint
active there satisfied at the origin, the segment towards the origin would stay in P and
shorten lambda), so each cable contributes one line: that of the bound nearer tau_p,i.
Along a line the other cables leave an interval of the line's parameter (the polygon's
edge on the line, empty when the line misses P), and the edge's point nearest the origin
is the foot of the origin on the line clipped to the edge. The answer is the nearest of
these m + 1 candidates. Each candidate meets the constraint of its own line exactly and
the others by construction of its edge, so no tolerance decides feasibility; a vertex is
reached as an edge's end.

The edges of all 2m lines also give the polygon's area centroid without ordering its
vertices: the shoelace sums run over the edges, each oriented by the side of its line the
polygon is on.

Cost for n = 6, m = 8 (ipanema8), in operations of the generated C: the QR of W^T and the
three products with Q about 1,000 (6 square roots, 12 divisions); the rows' products
m(m - 1)/2 = 28 pairs of about 10 (28 divisions); the edges m(m - 1) = 56 line-cable
pairs of about 16; the choice about 40 per line: 3,228 operations in all (the centroid,
on all 2m lines, 5,339). No iteration, no solver. Minimum and maximum are selects: the
generated C's fmin and fmax are library calls, several times slower.
"""

from __future__ import annotations

import dataclasses

import casadi as ca

from cdpr_sym.robot.tension_box import TensionBox

#: A cable whose row of N has a squared length at most this (a row of an orthonormal basis
#: has at most 1) has a tension the null space does not move: its lines do not exist, and
#: its tension tau_p,i alone must lie in the box.
STILL = 1e-24
#: A cross product a_i x a_k at most this small counts as zero (the cables' lines are
#: parallel); it is replaced by this value, so a parallel cable's interval lies beyond the
#: line's reach (:func:`_reach`) unless the cable's tension on the line is in its box.
PARALLEL = 1e-200


def orthogonal_split(W: ca.SX, w: ca.SX) -> tuple[ca.SX, ca.SX]:
    """(tau_p, N): the least-norm tension W^+ w (m,) in N and an orthonormal basis N (m x
    (m - n)) of the null space of W (n x m, full row rank), from a Householder QR of W^T.

    W^T = Q [R; 0] with Q = H_1 ... H_n; then N = Q [0; I] and tau_p = Q [R^-T w; 0], so
    tau_p is orthogonal to N to round-off. The reflections are a fixed sequence; each picks
    the sign that avoids cancellation with a select (a zero leading entry counts as
    positive, so no reflection degenerates while W has full row rank).
    """
    n, m = W.shape
    reflectors, R = _householder_qr(W.T)
    y = _forward_substitution(R.T, w)
    tau_p = _apply_q(reflectors, ca.vertcat(y, ca.SX.zeros(m - n)))
    columns = [_apply_q(reflectors, ca.DM.eye(m)[:, n + index]) for index in range(m - n)]
    return tau_p, ca.horzcat(*columns)


def _householder_qr(A: ca.SX) -> tuple[list[tuple[ca.SX, ca.SX]], ca.SX]:
    """(reflectors, R) of A (m x n, m >= n): H_j = I - beta_j v_j v_j^T acts on rows j:
    and H_n ... H_1 A = [R; 0] with R (n x n) upper triangular."""
    m, n = A.shape
    A = ca.SX(A)
    reflectors = []
    for j in range(n):
        x = A[j:, j]
        length = ca.norm_2(x)
        sign = ca.if_else(x[0] >= 0, 1.0, -1.0)
        v = ca.vertcat(x[0] + sign * length, x[1:])
        beta = 1.0 / (length * (length + ca.fabs(x[0])))  # 2 / |v|^2
        if j + 1 < n:
            rest = A[j:, j + 1:]
            A[j:, j + 1:] = rest - v @ (beta * (v.T @ rest))
        A[j, j] = -sign * length
        A[j + 1:, j] = ca.SX.zeros(m - j - 1)
        reflectors.append((v, beta))
    return reflectors, A[:n, :]


def _forward_substitution(L: ca.SX, b: ca.SX) -> ca.SX:
    """x with L x = b, L (n x n) lower triangular with a nonzero diagonal."""
    x = []
    for i in range(L.shape[0]):
        known = sum((L[i, k] * x[k] for k in range(i)), ca.SX(0))
        x.append((b[i] - known) / L[i, i])
    return ca.vertcat(*x)


def _apply_q(reflectors: list[tuple[ca.SX, ca.SX]], z: ca.SX) -> ca.SX:
    """Q z = H_1 (H_2 (... H_n z)) for the reflectors of :func:`_householder_qr`."""
    z = ca.SX(z)
    for j in reversed(range(len(reflectors))):
        v, beta = reflectors[j]
        z[j:] = z[j:] - v * (beta * ca.dot(v, z[j:]))
    return z


@dataclasses.dataclass(frozen=True)
class NullRows:
    """The rows a_i (2,) of N and the products lines built on them share.

    ``inverse[i]`` is 1 / |a_i|^2 where cable i's lines exist (``exists[i]``), else 0;
    ``gram[i, k]`` is a_i . a_k and ``slope_inverse[i, k]`` 1 / (a_i x a_k) (i < k, tiny
    cross products replaced by :data:`PARALLEL`).
    """

    rows: list[ca.SX]
    squared: list[ca.SX]
    exists: list[ca.SX]
    inverse: list[ca.SX]
    gram: dict[tuple[int, int], ca.SX]
    slope_inverse: dict[tuple[int, int], ca.SX]

    def pair(self, i: int, k: int) -> tuple[ca.SX, ca.SX]:
        """(a_i . a_k, 1 / (a_i x a_k)) for i != k."""
        if i < k:
            return self.gram[i, k], self.slope_inverse[i, k]
        return self.gram[k, i], -self.slope_inverse[k, i]


def null_rows(N: ca.SX) -> NullRows:
    """The :class:`NullRows` of N (m x 2)."""
    m = N.shape[0]
    rows = [N[i, :].T for i in range(m)]
    squared = [ca.dot(a, a) for a in rows]
    exists = [length > STILL for length in squared]
    inverse = [ca.if_else(e, 1.0 / ca.if_else(e, length, 1.0), 0.0)
               for e, length in zip(exists, squared, strict=True)]
    gram, slope_inverse = {}, {}
    for i in range(m):
        for k in range(i + 1, m):
            gram[i, k] = ca.dot(rows[i], rows[k])
            cross = rows[i][0] * rows[k][1] - rows[i][1] * rows[k][0]
            slope_inverse[i, k] = 1.0 / ca.if_else(ca.fabs(cross) > PARALLEL, cross, PARALLEL)
    return NullRows(rows, squared, exists, inverse, gram, slope_inverse)


@dataclasses.dataclass(frozen=True)
class Edge:
    """The feasible part of cable i's line at a bound: lambda = foot + s direction for
    low <= s <= high (empty when low > high; ``exists`` is 0 when the line does not).

    ``foot`` is the foot of the origin on the line; ``direction`` is a_i turned by +90
    degrees (orthogonal to the foot, as long as a_i)."""

    foot: ca.SX
    direction: ca.SX
    low: ca.SX
    high: ca.SX
    exists: ca.SX
    squared: ca.SX

    def at(self, s: ca.SX) -> ca.SX:
        """The point lambda of the line at parameter s."""
        return self.foot + s * self.direction

    @property
    def holds(self) -> ca.SX:
        """1 when the line exists and meets the polygon."""
        return ca.logic_and(self.exists, self.low <= self.high)


def edge(rows: NullRows, tau_p: ca.SX, i: int, bound: ca.SX | float, t_min: float,
         t_max: float) -> Edge:
    """The :class:`Edge` of cable i's line tau_i = ``bound`` (N).

    On it lambda = t a_i + s d_i with t = (bound - tau_p,i) / |a_i|^2, and cable k's tension
    is tau_p,k + t (a_i . a_k) + s (a_i x a_k): an interval of s centred where it is
    (t_min + t_max) / 2, half as wide as (t_max - t_min) / |a_i x a_k|.
    """
    a = rows.rows[i]
    t = (bound - tau_p[i]) * rows.inverse[i]
    box = TensionBox(t_min, t_max)
    middle, half = box.middle, box.half
    reach = _reach(t_min, t_max, tau_p.shape[0])
    low, high = ca.SX(-reach), ca.SX(reach)
    for k in range(tau_p.shape[0]):
        if k == i:
            continue
        gram, slope_inverse = rows.pair(i, k)
        centre = (middle - tau_p[k] - t * gram) * slope_inverse
        width = half * ca.fabs(slope_inverse)
        low, high = _larger(low, centre - width), _smaller(high, centre + width)
    return Edge(t * a, ca.vertcat(-a[1], a[0]), low, high, rows.exists[i], rows.squared[i])


def _reach(t_min: float, t_max: float, m: int) -> float:
    """A bound on |s| of every feasible point of every existing line: |s| |a_i| <= |lambda|
    <= |tau| <= sqrt(m) max(|t_min|, |t_max|), and |a_i| > sqrt(STILL)."""
    return (m ** 0.5) * max(abs(t_min), abs(t_max)) / STILL ** 0.5


def min_norm(W: ca.SX, w: ca.SX, t_min: float, t_max: float) -> tuple[ca.SX, ca.SX]:
    """(tau, feasible): the minimum-2-norm tension in [t_min, t_max]^m (N) producing w.

    Infeasible (0) when the polygon is empty; tau is then the middle of the crossed
    interval of the candidate line crossed least (the one-dimensional methods' rule, on
    that line), clipped to the box.
    """
    tau_p, N = orthogonal_split(W, w)
    rows = null_rows(N)
    middle = TensionBox(t_min, t_max).middle
    edges = [edge(rows, tau_p, i, ca.if_else(tau_p[i] < middle, t_min, t_max), t_min, t_max)
             for i in range(tau_p.shape[0])]
    origin = ca.logic_and(ca.mmin(tau_p) >= t_min, ca.mmax(tau_p) <= t_max)
    point, feasible = nearest(edges, origin)
    return finish(tau_p, N, point, feasible, edges, t_min, t_max)


def centroid(W: ca.SX, w: ca.SX, t_min: float, t_max: float) -> tuple[ca.SX, ca.SX]:
    """(tau, feasible): the tension (N) at the area centroid of the feasible polygon.

    A polygon of no area (a segment or a point, to round-off) has the minimum-norm tension
    instead, as has a centroid whose tension round-off put outside the box by more than
    1e-9 of the box; infeasible as in :func:`min_norm`.
    """
    tau_p, N = orthogonal_split(W, w)
    rows = null_rows(N)
    m = tau_p.shape[0]
    edges = [edge(rows, tau_p, i, bound, t_min, t_max)
             for i in range(m) for bound in (t_min, t_max)]
    origin = ca.logic_and(ca.mmin(tau_p) >= t_min, ca.mmax(tau_p) <= t_max)
    point, feasible = nearest(edges, origin)
    middle, area = area_centroid(edges)
    tau = tau_p + N @ middle
    slack = 1e-9 * (abs(t_min) + abs(t_max))
    inside = ca.logic_and(ca.mmin(tau) >= t_min - slack, ca.mmax(tau) <= t_max + slack)
    point = ca.if_else(ca.logic_and(area > 0, inside), middle, point)
    return finish(tau_p, N, point, feasible, edges, t_min, t_max)


def area_centroid(edges: list[Edge]) -> tuple[ca.SX, ca.SX]:
    """(centroid, twice the area) of the polygon from its edges (2 of each cable, at t_min
    then t_max), by the shoelace sums over the edges without ordering the vertices.

    The polygon lies on the side of t_min's line that a_i points to, on the left of
    -d_i: that edge runs from s = high to s = low, t_max's from low to high. For an edge
    from P1 = f + s1 d to P2 = f + s2 d, P1 x P2 = (s2 - s1) (f x d), and f x d = t |a_i|^2
    as f = t a_i; its shares are P1 x P2 of twice the area and (P1 + P2) P1 x P2 of six
    times the area times the centroid. The centroid is 0 where the area is.
    """
    doubled, moment = ca.SX(0.0), ca.SX.zeros(2)
    for index, side in enumerate(edges):
        forward = 1.0 if index % 2 else -1.0  # t_max's edge runs forward
        length = ca.if_else(side.holds, forward * (side.high - side.low), 0.0)
        along = side.foot[0] * side.direction[1] - side.foot[1] * side.direction[0]
        cross = length * along
        doubled = doubled + cross
        moment = moment + (2.0 * side.foot + (side.low + side.high) * side.direction) * cross
    safe = ca.if_else(doubled > 0, doubled, 1.0)
    return ca.if_else(doubled > 0, moment / (3.0 * safe), ca.SX.zeros(2)), doubled


def nearest(edges: list[Edge], origin: ca.SX) -> tuple[ca.SX, ca.SX]:
    """(lambda, found): the candidate nearest the origin among the origin (when ``origin``
    is 1) and each edge's point nearest it; found is 0 when there is none."""
    best = ca.SX.zeros(2)
    best_norm = ca.if_else(origin, 0.0, ca.inf)
    for candidate in edges:
        s = _smaller(_larger(ca.SX(0.0), candidate.low), candidate.high)
        norm = (ca.dot(candidate.foot, candidate.foot) + s * s * candidate.squared)
        take = ca.logic_and(candidate.holds, norm < best_norm)
        best = ca.if_else(take, candidate.at(s), best)
        best_norm = ca.if_else(take, norm, best_norm)
    return best, best_norm < ca.inf


def finish(tau_p: ca.SX, N: ca.SX, point: ca.SX, feasible: ca.SX, edges: list[Edge],
           t_min: float, t_max: float) -> tuple[ca.SX, ca.SX]:
    """(tau, feasible) at ``point`` when feasible, else at :func:`least_crossed`, clipped."""
    point = ca.if_else(feasible, point, least_crossed(edges))
    tau = tau_p + N @ point
    clipped = ca.vertcat(*[_smaller(_larger(tau[i], ca.SX(t_min)), ca.SX(t_max))
                           for i in range(tau.shape[0])])
    return ca.if_else(feasible, tau, clipped), ca.if_else(feasible, 1.0, 0.0)


def least_crossed(edges: list[Edge]) -> ca.SX:
    """The middle of the crossed interval of the existing line crossed least, measured
    along the line (|a_i| (low - high))."""
    best, best_crossing = ca.SX.zeros(2), ca.SX(ca.inf)
    for candidate in edges:
        crossing = (candidate.low - candidate.high) ** 2 * candidate.squared
        take = ca.logic_and(candidate.exists, crossing < best_crossing)
        best = ca.if_else(take, candidate.at(0.5 * (candidate.low + candidate.high)), best)
        best_crossing = ca.if_else(take, crossing, best_crossing)
    return best


def _larger(a: ca.SX, b: ca.SX) -> ca.SX:
    """max(a, b) as a select (exact; no library call in the generated C)."""
    return ca.if_else(a >= b, a, b)


def _smaller(a: ca.SX, b: ca.SX) -> ca.SX:
    """min(a, b) as a select."""
    return ca.if_else(a <= b, a, b)
