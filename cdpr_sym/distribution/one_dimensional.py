"""Exact tension distribution when the null space of W is one-dimensional (m = n + 1).

Every tension with W tau = w is tau = tau_p + s h: tau_p = W^+ w is orthogonal to the null
vector h, so the box leaves an interval [s_low, s_high] of s (empty: no tension in the box
produces w) and |tau|^2 = |tau_p|^2 + s^2 |h|^2. Hence the minimum-2-norm tension in the box
is at s = clip(0, s_low, s_high), and the centroid of the feasible set at the interval's
middle. A few dozen operations; no iteration, no solver.

**Guarded.** A tension held with margin keeps room for feedback: the minimum norm in the
box shrunk by g on each side, where that holds a tension. Where it does not, switching to
the full box's minimum norm would jump. :func:`guarded_min_norm` asks cable i to keep
w_i min(g, mu*) from the bounds instead, with mu* = max_s min_i (distance of cable i to
the nearer bound) / w_i the most any tension keeps (:func:`largest_margin`, closed form),
so the shrunk box always holds a tension, and it is the box shrunk by g wherever that one
holds one and every w_i is 1. The weight w_i = min(1, sqrt(m) |h_i| / |h|)
(:func:`room_weights`) lowers the room asked of a cable the internal force barely moves:
with equal weights such a cable inside the guard makes the set of tensions keeping mu*
grow from a point to a segment as its h_i passes zero, and the tension jumped by 85 N
there (a 3-cable example in the tests); weighted, its demand fades with h_i.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from cdpr_sym.distribution.interval import BIG, FLAT, feasible_interval

#: How far inside the largest margin mu* the guarded distribution keeps its margin, as a
#: share of the box width.
MARGIN_HAIR = 1e-9
#: The least weight a cable's room is divided by (:func:`largest_margin`).
WEIGHT_FLOOR = 1e-12


def null_vector(W: ca.SX) -> ca.SX:
    """A null vector h of W (n x (n + 1), full row rank): the column of the projector
    I - W^+ W with the largest diagonal entry (|h|^2 >= 1 / (n + 1) of a unit one)."""
    m = W.shape[1]
    projector = ca.SX.eye(m) - W.T @ ca.solve(W @ W.T, W)
    best, best_value = projector[:, 0], projector[0, 0]
    for index in range(1, m):
        better = projector[index, index] > best_value
        best = ca.if_else(better, projector[:, index], best)
        best_value = ca.if_else(better, projector[index, index], best_value)
    return best


def tension_interval(W: ca.SX, w: ca.SX, t_min: float, t_max: float
                     ) -> tuple[ca.SX, ca.SX, ca.SX, ca.SX]:
    """(tau_p, h, s_low, s_high): every feasible tension is tau_p + s h, s_low <= s <= s_high."""
    m = W.shape[1]
    tau_p = W.T @ ca.solve(W @ W.T, w)
    h = null_vector(W)
    s_low, s_high = feasible_interval(tau_p, h, ca.DM.ones(m) * t_min, ca.DM.ones(m) * t_max)
    return tau_p, h, s_low, s_high


def min_norm(W: ca.SX, w: ca.SX, t_min: float, t_max: float) -> tuple[ca.SX, ca.SX]:
    """(tau, feasible): the minimum-2-norm tension in the box producing w. Infeasible (0):
    the interval is empty and tau is taken at its crossed middle, clipped to the box."""
    return _at(W, w, t_min, t_max, lambda low, high: ca.fmin(ca.fmax(0.0, low), high))


def room_weights(h: ca.SX) -> ca.SX:
    """w_i = min(1, sqrt(m) |h_i| / |h|): how much of the guard cable i is asked to keep.
    The internal force moves cable i by h_i per unit; a cable it moves as much as an even
    share (|h_i| >= |h| / sqrt(m)) keeps all of it, one it barely moves proportionally
    less, one it does not move none (room there is not the internal force's to give)."""
    m = h.shape[0]
    return ca.fmin(1.0, np.sqrt(m) * ca.fabs(h) / ca.fmax(ca.norm_2(h), FLAT))


def largest_margin(tau_p: ca.SX, h: ca.SX, t_min: float, t_max: float,
                   weights: ca.SX | None = None) -> ca.SX:
    """mu* = max over s of min over cables of the distance of tau_p + s h to the box's
    nearer bound over the cable's weight w_i (1 without ``weights``), N (negative: no
    tension in the box). Each cable gives two affine scaled distances of s, slopes
    h_i / w_i and -h_i / w_i; the maximum of their minimum is, by the 1-D LP's duality,
    the least of the crossings of one rising line (a_k + b_k s, b_k > 0) with one falling
    line (a_l + b_l s, b_l < 0), (a_k |b_l| + a_l b_k) / (b_k + |b_l|), and of the constant
    distances of cables the null space does not move (|b_k| <= FLAT)."""
    m = tau_p.shape[0]
    scale = ca.DM.ones(m) if weights is None else ca.fmax(weights, WEIGHT_FLOOR)
    lines = [((tau_p[i] - t_min) / scale[i], h[i] / scale[i]) for i in range(m)] + \
        [((t_max - tau_p[i]) / scale[i], -h[i] / scale[i]) for i in range(m)]
    candidates = []
    for a_k, b_k in lines:
        candidates.append(ca.if_else(ca.fabs(b_k) <= FLAT, a_k, BIG))
        for a_l, b_l in lines:
            crossing = (a_k * (-b_l) + a_l * b_k) / ca.fmax(b_k - b_l, FLAT)
            candidates.append(ca.if_else(ca.logic_and(b_k > FLAT, b_l < -FLAT), crossing,
                                         BIG))
    return ca.mmin(ca.vertcat(*candidates))


def guarded_min_norm(W: ca.SX, w: ca.SX, t_min: float, t_max: float, guard: float
                     ) -> tuple[ca.SX, ca.SX]:
    """(tau, feasible): the minimum-2-norm tension producing w whose every cable i keeps
    w_i min(``guard``, mu*) (N) from the box's bounds (w_i :func:`room_weights`, mu* the
    most any tension keeps so, :func:`largest_margin`; module notes); infeasible as in
    :func:`min_norm`. ``guard`` 0 is :func:`min_norm`."""
    tau_p, h, low, high = tension_interval(W, w, t_min, t_max)
    m = W.shape[1]
    weights = room_weights(h)
    # a hair inside mu*, so the interval is not lost to rounding where mu* binds
    kept = ca.fmax(ca.fmin(guard, largest_margin(tau_p, h, t_min, t_max, weights)
                           - MARGIN_HAIR * (t_max - t_min)), 0.0)
    low_g, high_g = feasible_interval(tau_p, h, ca.DM.ones(m) * t_min + kept * weights,
                                      ca.DM.ones(m) * t_max - kept * weights)
    middle = 0.5 * (low_g + high_g)  # where rounding still crosses them: the crossing
    guarded = ca.fmin(ca.fmax(0.0, ca.fmin(low_g, middle)), ca.fmax(high_g, middle))
    feasible = low <= high
    s = ca.if_else(feasible, ca.fmin(ca.fmax(guarded, low), high), 0.5 * (low + high))
    tau = tau_p + s * h
    return (ca.if_else(feasible, tau, ca.fmin(ca.fmax(tau, t_min), t_max)),
            ca.if_else(feasible, 1.0, 0.0))


def centroid(W: ca.SX, w: ca.SX, t_min: float, t_max: float) -> tuple[ca.SX, ca.SX]:
    """(tau, feasible): the middle of the feasible segment (its centroid); infeasible as
    in :func:`min_norm`."""
    return _at(W, w, t_min, t_max, lambda low, high: 0.5 * (low + high))


def _at(W: ca.SX, w: ca.SX, t_min: float, t_max: float, choose) -> tuple[ca.SX, ca.SX]:
    tau_p, h, low, high = tension_interval(W, w, t_min, t_max)
    feasible = low <= high
    s = ca.if_else(feasible, choose(low, high), 0.5 * (low + high))
    tau = tau_p + s * h
    return (ca.if_else(feasible, tau, ca.fmin(ca.fmax(tau, t_min), t_max)),
            ca.if_else(feasible, 1.0, 0.0))
