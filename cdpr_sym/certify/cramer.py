"""Cramer's margins: the static (and wrench) workspace of m = n <= :data:`CRAMER_UP_TO`.

A pose q is statically feasible when the unique tension holding the platform at rest there,
T = W(q)^{-1} grad V(q), lies in [T_min, T_max] on every cable. By Cramer's rule
T_i = N_i / D with D = det W and N_i the determinant of W with column i replaced by grad V,
so on a box where D keeps one sign s:

* every pose of the box is feasible iff s (N_i - T_min D) >= 0 and s (T_max D - N_i) >= 0
  for every i, which the interval enclosures prove when their lower bounds are >= 0;
* every pose is infeasible when, for some i, one of these is < 0 on the whole box (an
  upper bound < 0).

These margins are polynomials of W's entries, free of the division's dependency; each is
enclosed by the mean-value form (:mod:`cdpr_sym.certify.enclosure`), rounded outward.

**Against a wrench box** (half-widths h: force N, moment N m): W T = grad V - J^T w. T is
affine in w, so over the box T_i ranges over T_i(0) -+ sum_j |B_ij| h_j / |D| with B_ij the
determinant of W with column i replaced by (J^T)_j; the margins become s (N_i - T_min D) -
P_i and s (T_max D - N_i) - P_i with P_i = sum_j |B_ij| h_j, enclosed the same way (|.| has
slopes sign(.) in [-1, 1], the generalized gradient the mean-value form needs).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from cdpr_sym.certify.enclosure import enclosure
from cdpr_sym.certify.poses import pose_inputs
from cdpr_sym.certify.verdict import BoxVerdicts, decide
from cdpr_sym.model import SymbolicModel
from cdpr_sym.robot import Robot

#: Largest n decided by Cramer's polynomial margins (determinants by minors grow as n!);
#: beyond, by Krawczyk's method on the interval system [W] T = [grad V]
#: (:mod:`cdpr_sym.certify.krawczyk`). (The tension of CasADi's symbolic QR solve, tried
#: for spatial6, encloses +-0.26 N on a box 2 um wide and the whole line at 1 mm: its
#: divisions' dependency.)
CRAMER_UP_TO = 3


def margin_function(model: SymbolicModel, orientation: np.ndarray,
                    half_widths: np.ndarray | None = None) -> ca.Function:
    """positions (d) -> [D, N_i - T_min D (n), T_max D - N_i (n)] at the fixed
    ``orientation`` (``None``: of the whole pose, n); with wrench ``half_widths`` (not all
    zero) -> [D, those margins less P_i (2n), their negatives less P_i (2n)], the second
    block for D < 0 (module docstring)."""
    robot = model.robot
    position, q = pose_inputs(robot, orientation)
    W = model.structure_matrix(q)
    gravity = model.grad_potential(q)
    determinant = ca.det(W)
    numerators = []
    for i in range(model.n):
        replaced = ca.horzcat(*(gravity if j == i else W[:, j] for j in range(model.n)))
        numerators.append(ca.det(replaced))
    numerator = ca.vertcat(*numerators)
    margins = ca.vertcat(numerator - robot.t_min * determinant,
                         robot.t_max * determinant - numerator)
    if half_widths is None or not np.any(half_widths):
        return ca.Function("margins", [position], [ca.vertcat(determinant, margins)])
    transposed = model.wrench_jacobian(q).T  # columns: generalized force of each wrench axis
    spread = []
    for i in range(model.n):
        total = 0
        for j, h in enumerate(half_widths):
            if h:
                replaced = ca.horzcat(*(transposed[:, j] if k == i else W[:, k]
                                        for k in range(model.n)))
                total = total + float(h) * ca.fabs(ca.det(replaced))
        spread.append(total)
    spread = ca.vertcat(*spread, *spread)
    return ca.Function("wrench_margins", [position],
                       [ca.vertcat(determinant, margins - spread, -margins - spread)])


class CramerVerdicts:
    """Verdicts from Cramer's margins (m = n <= :data:`CRAMER_UP_TO`)."""

    def __init__(self, model: SymbolicModel, orientation: np.ndarray, compiled: bool) -> None:
        self.margins = enclosure(margin_function(model, orientation), compiled)
        self.n = model.n

    def __call__(self, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
        return _verdicts(self.margins((lower.T, upper.T))[0], self.n)


class WrenchCramerVerdicts:
    """Verdicts from Cramer's margins less the wrench box's spread (module docstring)."""

    def __init__(self, model: SymbolicModel, orientation: np.ndarray, half_widths: np.ndarray,
                 compiled: bool) -> None:
        self.margins = enclosure(margin_function(model, orientation, half_widths), compiled)
        self.n = model.n

    def __call__(self, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
        lo, hi = self.margins((lower.T, upper.T))[0]
        n2 = 2 * self.n
        positive, negative = lo[0] > 0, hi[0] < 0
        return decide(positive | negative, np.where(positive, lo[1:1 + n2], lo[1 + n2:]),
                      np.where(positive, hi[1:1 + n2], hi[1 + n2:]))


def _verdicts(bounds, n: int) -> np.ndarray:
    """A :class:`~cdpr_sym.certify.verdict.Verdict` code per box from the margins'
    enclosures (module docstring)."""
    lo, hi = bounds
    det_lo, det_hi = lo[0], hi[0]
    positive, negative = det_lo > 0, det_hi < 0
    # s * margin for the sign s of D: lower and upper bounds
    return decide(positive | negative, np.where(positive, lo[1:], -hi[1:]),
                  np.where(positive, hi[1:], -lo[1:]))


class CramerMethod:
    """Static feasibility by Cramer's margins: m = n <= :data:`CRAMER_UP_TO`, no wrench."""

    key = "cramer"
    description = "Cramer's margins s (N_i - T_min D), s (T_max D - N_i), mean-value form"

    def covers(self, robot: Robot, wrench: bool) -> bool:
        return robot.m == robot.n <= CRAMER_UP_TO and not wrench

    def verdicts(self, model: SymbolicModel, orientation: np.ndarray | None, compiled: bool,
                 wrench: np.ndarray | None) -> BoxVerdicts:
        return CramerVerdicts(model, orientation, compiled)


class WrenchCramerMethod:
    """Wrench feasibility by Cramer's margins less the wrench box's spread: m = n <=
    :data:`CRAMER_UP_TO`."""

    key = "cramer-wrench"
    description = "Cramer's margins less the wrench box's spread, mean-value form"

    def covers(self, robot: Robot, wrench: bool) -> bool:
        return robot.m == robot.n <= CRAMER_UP_TO and wrench

    def verdicts(self, model: SymbolicModel, orientation: np.ndarray | None, compiled: bool,
                 wrench: np.ndarray | None) -> BoxVerdicts:
        return WrenchCramerVerdicts(model, orientation, wrench, compiled)
