"""Exact tension distribution when the null space of W is one-dimensional (m = n + 1).

Every tension with W tau = w is tau = tau_p + s h: tau_p = W^+ w is orthogonal to the null
vector h, so the box leaves an interval [s_low, s_high] of s (empty: no tension in the box
produces w) and |tau|^2 = |tau_p|^2 + s^2 |h|^2. Hence the minimum-2-norm tension in the box
is at s = clip(0, s_low, s_high), and the centroid of the feasible set at the interval's
middle. A few dozen operations; no iteration, no solver.
"""

from __future__ import annotations

import casadi as ca

from cdpr_sym.distribution.interval import feasible_interval


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
