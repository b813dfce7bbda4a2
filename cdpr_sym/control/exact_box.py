"""Tension designs that use the exact box T_min <= tau <= T_max: ``box`` and ``linf``.

Both choose alpha (the scale on the PD part) and the interconnection entries j per control
step, exactly rather than through the triangle inequality of (18).

Geometry. With A = W^{-1} P(dq) of rank n - 1, the interconnection tension tau_3 = A j can
be any vector of the plane {y : v^T y = 0}, v = W^T dq (the left null vector of A; v^T tau
is the power the cables put in, divided by ||dq||). So, for a given alpha, the reachable
tensions form the hyperplane H(alpha) = {tau : v^T tau = v^T (tau_1 + alpha tau_2)}, and

* the largest alpha in [0, 1] for which H(alpha) meets the box has a closed form (a
  one-dimensional interval test), and
* the command is the point of H(alpha) inside a box closest (in the 2-norm) to the PD command
  tau_1 + alpha tau_2: the smallest interconnection tension that makes it feasible.

``box`` projects onto H ∩ [T_min, T_max]. ``linf`` first finds t* = min over H of
||tau - (T_min + T_max)/2||_inf (the paper's (16), future work) and projects onto H ∩ the
box shrunk to that l∞ ball widened by ``linf_slack`` N. The projection is unique and
continuous in the data (strictly convex objective), though steep where a component of v is
near zero (a 5e-13 change of alpha moved the command by 2e-5 N in one such state);
``linf_slack = 0`` gives the bare l∞
optimum, a box corner that jumps whenever a component of v changes sign, which is why the
default keeps a slack. j is reported as the minimum-norm representative A^+ tau_3.

Fallbacks (flags of :mod:`cdpr_sym.control.flags`): below ``low_speed`` A ≈ 0, j = 0 and
alpha is the largest value keeping tau_1 + alpha tau_2 in the box (FLAG_LOW_SPEED). Where no
alpha in (0, 1] makes the box reachable, the command is PD + gravity compensation clipped to
the box (FLAG_INFEASIBLE and FLAG_SATURATED).

The projection is solved exactly with a branch-free breakpoint search (2n candidate
multipliers), so the whole law is a CasADi expression that is generated to C with the step.
:mod:`cdpr_sym.control.cvx_reference` states the same problems in cvxpy as the reference.
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import casadi as ca
import numpy as np

from cdpr_sym.control.flags import (
    FLAG_ALPHA,
    FLAG_INFEASIBLE,
    FLAG_LOW_SPEED,
    FLAG_SATURATED,
    FLAG_SINGULAR,
)
from cdpr_sym.control.interface import Capabilities, ControlLaw, StatelessLaw
from cdpr_sym.control.parts import (
    alpha_interval,
    beta_margin,
    clip_to_box,
    flag_if,
    least_squares_min_norm,
    tension_parts,
)
from cdpr_sym.distribution.interval import BIG
from cdpr_sym.errors import InvalidCase
from cdpr_sym.model import SymbolicModel


def project_box_hyperplane(p: ca.SX, v: ca.SX, c: ca.SX, lower: ca.SX,
                           upper: ca.SX) -> ca.SX:
    """argmin ||x - p||_2 subject to lower <= x <= upper and v^T x = c (assumed feasible).

    The minimiser is x(lam) = clip(p + lam v, lower, upper) with g(lam) = v^T x(lam) = c;
    g is non-decreasing and piecewise linear with breakpoints where a component reaches a
    bound, so lam is found exactly by bracketing c between breakpoints.
    """
    n = p.shape[0]
    active = ca.fabs(v) > 1e-12
    safe_v = ca.if_else(active, v, 1.0)
    breakpoints = ca.vertcat(ca.if_else(active, (lower - p) / safe_v, 0.0),
                             ca.if_else(active, (upper - p) / safe_v, 0.0))

    def g(lam: ca.SX) -> ca.SX:
        return ca.dot(v, ca.fmin(ca.fmax(p + lam * v, lower), upper))

    values = [g(breakpoints[k]) for k in range(2 * n)]
    lam_low, lam_high = -BIG, BIG
    g_low, g_high = -BIG, BIG
    for k in range(2 * n):
        below = values[k] <= c
        better_low = ca.logic_and(below, breakpoints[k] > lam_low)
        lam_low = ca.if_else(better_low, breakpoints[k], lam_low)
        g_low = ca.if_else(better_low, values[k], g_low)
        above = values[k] >= c
        better_high = ca.logic_and(above, breakpoints[k] < lam_high)
        lam_high = ca.if_else(better_high, breakpoints[k], lam_high)
        g_high = ca.if_else(better_high, values[k], g_high)
    has_low, has_high = lam_low > -BIG, lam_high < BIG
    span = g_high - g_low
    interpolated = lam_low + (c - g_low) * (lam_high - lam_low) / ca.if_else(
        ca.fabs(span) > 0, span, 1.0)
    lam = ca.if_else(ca.logic_and(has_low, has_high),
                     ca.if_else(ca.fabs(span) > 0, interpolated, lam_low),
                     ca.if_else(has_low, lam_low, ca.if_else(has_high, lam_high, 0.0)))
    return ca.fmin(ca.fmax(p + lam * v, lower), upper)


@dataclasses.dataclass(frozen=True)
class _ExactBoxDesign(StatelessLaw):
    """Shared law of ``box`` and ``linf``; see the module docstring.

    Parameters
    ----------
    low_speed : float
        Threshold on ||dq||, m/s: below it A ~ 0, j = 0 and only alpha acts (FLAG_LOW_SPEED).
    alpha_margin : float
        Relative margin taken off the largest feasible alpha, so the command stays strictly
        inside the box under round-off.
    linf_slack : float or None
        ``linf`` only: the box is shrunk to the l∞ optimum t* widened by this slack, N;
        None (``box``) keeps the whole box.
    """

    low_speed: float = 1e-6
    alpha_margin: float = 1e-6
    linf_slack: float | None = None
    name: ClassVar[str] = "exact-box"

    def capabilities(self) -> Capabilities:
        """m = n cables (it inverts W), every period in the step; its gain scaled by alpha
        (the largest the box allows)."""
        return Capabilities(scales_gain=True)

    def __post_init__(self) -> None:
        for field in ("low_speed", "alpha_margin"):
            value = getattr(self, field)
            if not (np.isfinite(value) and value > 0):
                raise InvalidCase(field, f"expected a positive number, got {value}")
        if self.linf_slack is not None and not (np.isfinite(self.linf_slack)
                                                and self.linf_slack >= 0):
            raise InvalidCase("linf_slack", f"expected a slack >= 0 N, got {self.linf_slack}")

    def options(self) -> dict[str, Any]:
        out = {"low_speed": self.low_speed, "alpha_margin": self.alpha_margin}
        if self.linf_slack is not None:
            out["linf_slack"] = self.linf_slack
        return out

    def law(self, model: SymbolicModel, q: ca.SX, dq: ca.SX, q_goal: ca.SX, k: ca.SX,
            r_d: ca.SX) -> ControlLaw:
        parts = tension_parts(model, q, dq, q_goal, k, r_d)
        t_min, t_max = model.robot.t_min, model.robot.t_max
        mid, n = model.robot.box.middle, model.n
        tau_1, tau_2 = parts.tau_1, parts.tau_2_full
        speed = ca.norm_2(dq)
        slow = speed < self.low_speed
        direction = dq / ca.fmax(speed, self.low_speed)
        v = parts.W.T @ direction
        v = v / ca.fmax(ca.norm_2(v), 1e-300)

        # alpha: the hyperplane through tau_1 + alpha tau_2 must meet the box
        plane_low = ca.sum1(ca.fmin(v * t_min, v * t_max))
        plane_high = ca.sum1(ca.fmax(v * t_min, v * t_max))
        fast_low, fast_high = alpha_interval(ca.dot(v, tau_1), ca.dot(v, tau_2),
                                             plane_low, plane_high)
        slow_low, slow_high = alpha_interval(tau_1, tau_2, ca.DM.ones(n) * t_min,
                                             ca.DM.ones(n) * t_max)
        low = ca.if_else(slow, slow_low, fast_low)
        high = ca.if_else(slow, slow_high, fast_high)
        feasible = ca.logic_and(low <= high, high > 0)
        alpha = ca.if_else(high < 1, high * (1 - self.alpha_margin), 1.0)
        alpha = ca.fmax(alpha, ca.fmin(low, high))

        tau_pd = tau_1 + alpha * tau_2
        box_low, box_high = ca.DM.ones(n) * t_min, ca.DM.ones(n) * t_max
        if self.linf_slack is not None:
            distance = ca.fabs(ca.dot(v, tau_pd) - mid * ca.sum1(v)) / ca.fmax(
                ca.sum1(ca.fabs(v)), 1e-300)
            radius = distance + self.linf_slack
            box_low, box_high = ca.fmax(box_low, mid - radius), ca.fmin(box_high, mid + radius)
        tau_fast = project_box_hyperplane(tau_pd, v, ca.dot(v, tau_pd), box_low, box_high)

        A_unit = parts.W_inv @ model.p_matrix(direction)
        j_fast = least_squares_min_norm(A_unit, tau_fast - tau_pd, v) / ca.fmax(
            speed, self.low_speed)
        tau_sat, _ = clip_to_box(model, tau_1 + tau_2)
        tau = ca.if_else(feasible, ca.if_else(slow, tau_pd, tau_fast), tau_sat)
        alpha = ca.if_else(feasible, alpha, 1.0)
        j = ca.if_else(ca.logic_or(slow, ca.logic_not(feasible)), ca.SX.zeros(model.n_j), j_fast)
        flags = (flag_if(slow, FLAG_LOW_SPEED) + flag_if(ca.logic_not(feasible), FLAG_INFEASIBLE)
                 + flag_if(ca.logic_not(feasible), FLAG_SATURATED) + flag_if(alpha < 1, FLAG_ALPHA)
                 + flag_if(parts.singular, FLAG_SINGULAR))
        return ControlLaw(tau, alpha, beta_margin(model, tau_1), j, flags)


@dataclasses.dataclass(frozen=True)
class BoxDesign(_ExactBoxDesign):
    """Largest alpha for which the exact tension box is reachable, smallest J_d tension.

    Guarantee: wherever FLAG_INFEASIBLE is not raised, T_min <= tau <= T_max exactly (no
    triangle-inequality conservatism), and alpha is the largest value in [0, 1] (less a
    relative ``alpha_margin``) for which that is possible.
    """

    name: ClassVar[str] = "box"


@dataclasses.dataclass(frozen=True)
class LinfDesign(_ExactBoxDesign):
    """Box-feasible alpha as in :class:`BoxDesign`, tensions centred in the l∞ sense (16).

    Guarantee: as :class:`BoxDesign`, and ||tau - mid||_inf <= t* + ``linf_slack`` where t*
    is the l∞ optimum over the reachable hyperplane at the chosen alpha.
    """

    linf_slack: float | None = 1.0
    name: ClassVar[str] = "linf"
