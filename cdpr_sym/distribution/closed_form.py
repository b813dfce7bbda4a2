"""Pott's closed-form tension distribution and its improved variant, in CasADi.

For a wrench w (n) to be produced by m >= n cables with W tau = w, the closed-form method
takes the tension nearest, in the 2-norm, to the middle of the box:

    tau = tau_mid + W^+ (w - W tau_mid),   W^+ = W^T (W W^T)^{-1},

and is feasible when that tau lies in [t_min, t_max] (Pott, Bruckmann and Mikelsons,
"Closed-form force distribution for parallel wire robots", Computational Kinematics 2009).
The improved method (Pott, "An improved force distribution algorithm for over-constrained
cable-driven parallel robots", Computational Kinematics 2014) repairs a violation: it fixes
the cable that violates its bound the most at that bound, removes it, and solves again with
the others, up to m - n times; with n cables left the solve is square and final.
Both are branch-free here (masks and selects), so they generate straight-line C.
"""

from __future__ import annotations

import casadi as ca

from cdpr_sym.linalg import ldl_solve, weighted_gram
from cdpr_sym.robot.tension_box import TensionBox

#: Largest residual |W tau - w|_inf, relative to 1 + |w|_inf, of a tension called feasible.
RESIDUAL = 1e-9


def closed_form(W: ca.SX, w: ca.SX, t_min: float, t_max: float) -> tuple[ca.SX, ca.SX]:
    """(tau, feasible) of the closed-form method: tau (m,) in N; feasible is 1 when every
    entry is inside [t_min, t_max], else 0 (tau is then returned as computed, unclipped)."""
    m = W.shape[1]
    free = ca.DM.ones(m)
    tau = _nearest_to_middle(W, weighted_gram(W), w, free, ca.SX.zeros(m), t_min, t_max)
    return tau, _inside(tau, t_min, t_max)


def nearest_to(W: ca.SX, w: ca.SX, preferred: ca.SX) -> ca.SX:
    """The tension (m,) nearest, in the 2-norm, to ``preferred`` (N) with W tau = w:
    preferred + W^+ (w - W preferred), the closed form about another point than the box's
    middle (no box test: the caller checks it). Linear in w; ``preferred`` itself where it
    produces w already."""
    return preferred + W.T @ ldl_solve(weighted_gram(W), w - W @ preferred)


def improved_closed_form(W: ca.SX, w: ca.SX, t_min: float, t_max: float
                         ) -> tuple[ca.SX, ca.SX]:
    """(tau, feasible) of the improved closed-form method (m - n repairs at most).

    A repair fixes the free cable with the largest violation of its box at the bound it
    violates. Infeasible (0) when tension outside the box remains after the last repair, or
    when the cables left free no longer produce w (they align); tau is then the last
    solve's, unclipped.
    """
    n, m = W.shape
    free = ca.SX.ones(m)  # 1 for a cable still to be solved for
    fixed = ca.SX.zeros(m)  # the tension of the fixed cables (0 for the free ones), N
    gram = weighted_gram(W)  # W_f W_f^T of the free cables
    tau = _nearest_to_middle(W, gram, w, free, fixed, t_min, t_max)
    for _ in range(m - n):
        violation = free * ca.fmax(ca.fmax(tau - t_max, t_min - tau), 0.0)
        worst = _first_largest(violation)
        repair = ca.mmax(violation) > 0
        bound = ca.if_else(tau > t_max, t_max, t_min)
        chosen = repair * worst
        fixed = fixed + chosen * bound
        free = free - chosen
        column = W @ chosen  # the fixed cable's column (0 without a repair)
        gram = gram - column @ column.T  # its term leaves W_f W_f^T: no new product
        tau = ca.if_else(repair, _nearest_to_middle(W, gram, w, free, fixed, t_min, t_max),
                         tau)
    # the repairs can leave free cables that no longer span the wrench space (on lines where
    # cables align): the solve then returns numbers in the box that do not produce w
    produces = ca.norm_inf(W @ tau - w) <= RESIDUAL * (1.0 + ca.norm_inf(w))
    return tau, _inside(tau, t_min, t_max) * ca.if_else(produces, 1.0, 0.0)


def _nearest_to_middle(W: ca.SX, gram: ca.SX, w: ca.SX, free: ca.SX, fixed: ca.SX,
                       t_min: float, t_max: float) -> ca.SX:
    """The free cables' tension nearest the box's middle with W tau = w, the fixed ones at
    ``fixed``: tau_f = mid + W_f^T (W_f W_f^T)^{-1} (w - W (fixed + mid free)), with
    ``gram`` = W_f W_f^T and W_f = W diag(free) applied as a mask on vectors."""
    start = fixed + TensionBox(t_min, t_max).middle * free
    # W_f W_f^T is symmetric positive (semi-)definite: LDL^T, a fifth of a symbolic QR's
    # operations; where the free cables stop spanning the wrench space the residual test
    # of the caller decides
    return start + free * (W.T @ ldl_solve(gram, w - W @ start))


def _first_largest(values: ca.SX) -> ca.SX:
    """One-hot vector of the first largest entry of ``values``."""
    largest = ca.mmax(values)
    taken = ca.SX(0)
    hot = []
    for index in range(values.shape[0]):
        is_it = ca.logic_and(values[index] >= largest, taken == 0)
        hot.append(ca.if_else(is_it, 1.0, 0.0))
        taken = taken + hot[-1]
    return ca.vertcat(*hot)


def _inside(tau: ca.SX, t_min: float, t_max: float) -> ca.SX:
    """1 when every entry of tau lies in [t_min, t_max], else 0."""
    return ca.if_else(ca.logic_and(ca.mmin(tau) >= t_min, ca.mmax(tau) <= t_max), 1.0, 0.0)
