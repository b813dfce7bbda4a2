"""Hyperplane shifting over boxes: the static or wrench workspace of m > n robots (n <=
:data:`~cdpr_sym.certify.cramer.CRAMER_UP_TO`), and of m = n robots against a wrench box
beyond it.

For each set F of n - 1 columns of W with normal c, the facet margin
1/2 (T_max - T_min) sum_j |c . w_j| - |c . (grad V - W tau_mid)| - sum_i |(J c)_i| h_i
is >= 0 at a pose where every wrench of the box is held (hyperplane shifting, as the sampled
workspace does it, :mod:`cdpr_sym.workspace.wrench`). Every facet margin >= 0 on the box and
some facet spread sum_j |c . w_j| > 0 on it (W of full rank at every pose) prove it
feasible; a facet margin < 0 on the whole box proves it infeasible.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from cdpr_sym.certify.cramer import CRAMER_UP_TO
from cdpr_sym.certify.enclosure import enclosure
from cdpr_sym.certify.poses import pose_inputs
from cdpr_sym.certify.verdict import BoxVerdicts, codes
from cdpr_sym.model import SymbolicModel
from cdpr_sym.robot import Robot
from cdpr_sym.workspace.wrench import facet_normals, facet_projections


def facet_function(model: SymbolicModel, orientation: np.ndarray,
                   half_widths: np.ndarray | None = None) -> ca.Function:
    """positions (d) -> [margin_F (facets), spread_F (facets)] at the fixed ``orientation``,
    per set F of n - 1 columns of W with normal c (module docstring, hyperplane shifting):
    margin_F = (T_max - T_min) / 2 spread_F - |c . (grad V - W tau_mid)| - sum_i |(J c)_i| h_i,
    spread_F = sum_j |c . w_j|."""
    robot = model.robot
    position, q = pose_inputs(robot, orientation)
    W = model.structure_matrix(q)
    mid, half = robot.box.middle, robot.box.half
    offset = model.grad_potential(q) - W @ ca.DM.ones(model.m) * mid
    J = model.wrench_jacobian(q)
    normals = facet_normals(W)
    margins, spreads = [], []
    for (_, c), projections in zip(normals, facet_projections(W, normals), strict=True):
        spread = ca.sum1(ca.fabs(projections))
        required = ca.fabs(ca.dot(c, offset))
        if half_widths is not None:
            required = required + ca.dot(ca.fabs(J @ c), ca.DM(half_widths))
        margins.append(half * spread - required)
        spreads.append(spread)
    return ca.Function("facets", [position], [ca.vertcat(*margins, *spreads)])


class FacetVerdicts:
    """Verdicts by hyperplane shifting over boxes (any m >= n, a wrench box or none): a box is
    feasible when every facet's margin is >= 0 on it and some facet's spread is > 0 on it (so
    W has full rank at every pose: some n x n minor is nonzero), infeasible when some
    facet's margin is < 0 on it (a support inequality, necessary at any rank)."""

    def __init__(self, model: SymbolicModel, orientation: np.ndarray,
                 half_widths: np.ndarray | None, compiled: bool) -> None:
        function = facet_function(model, orientation, half_widths)
        self.facets = function.nnz_out(0) // 2
        self.margins = enclosure(function, compiled)

    def __call__(self, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
        lo, hi = self.margins((lower.T, upper.T))[0]
        k = self.facets
        full_rank = np.any(lo[k:] > 0, axis=0)
        feasible = full_rank & np.all(lo[:k] >= 0, axis=0)
        infeasible = np.any(hi[:k] < 0, axis=0)
        return codes(feasible, infeasible)


class FacetMethod:
    """Hyperplane shifting over boxes: m > n with n <= :data:`CRAMER_UP_TO` (a wrench box
    or none), or m = n > :data:`CRAMER_UP_TO` against a wrench box."""

    key = "facets"
    description = "hyperplane shifting over boxes: every facet margin enclosed"

    def covers(self, robot: Robot, wrench: bool) -> bool:
        return ((robot.m > robot.n and robot.n <= CRAMER_UP_TO)
                or (robot.m == robot.n > CRAMER_UP_TO and wrench))

    def verdicts(self, model: SymbolicModel, orientation: np.ndarray | None, compiled: bool,
                 wrench: np.ndarray | None) -> BoxVerdicts:
        return FacetVerdicts(model, orientation, wrench, compiled)
