"""Krawczyk's method: the static workspace of m = n > :data:`~cdpr_sym.certify.cramer.
CRAMER_UP_TO` without a wrench box.

Determinants by minors grow as n!, so beyond three degrees of freedom the entries of W and
grad V are enclosed over the box (mean-value form, :mod:`cdpr_sym.certify.enclosure`) and
the interval system [W] T = [grad V] solved by Krawczyk's method
(:mod:`cdpr_sym.certify.linear`), which proves W regular on the box or decides nothing.
A box is feasible when every enclosed T_i lies in [T_min, T_max], infeasible when some
enclosed T_i lies wholly outside it.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from cdpr_sym.certify.cramer import CRAMER_UP_TO
from cdpr_sym.certify.enclosure import enclosure
from cdpr_sym.certify.linear import enclose_solutions
from cdpr_sym.certify.poses import pose_inputs
from cdpr_sym.certify.verdict import BoxVerdicts, codes
from cdpr_sym.model import SymbolicModel
from cdpr_sym.robot import Robot


class KrawczykVerdicts:
    """Verdicts from the enclosed solutions of [W] T = [grad V] (:mod:`.linear`): W's and
    grad V's entries enclosed by the mean-value form, the system by Krawczyk's method,
    which also proves W regular on the box (else nothing is decided)."""

    def __init__(self, model: SymbolicModel, orientation: np.ndarray, compiled: bool) -> None:
        robot = model.robot
        position, q = pose_inputs(robot, orientation)
        terms = ca.Function("terms", [position], [ca.vertcat(
            ca.vec(ca.densify(model.structure_matrix(q))), model.grad_potential(q))])
        self.terms = enclosure(terms, compiled)
        self.n, self.t_min, self.t_max = model.n, robot.t_min, robot.t_max

    def __call__(self, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
        n = self.n
        lo, hi = self.terms((lower.T, upper.T))[0]
        boxes = lo.shape[1]
        W_lo = lo[: n * n].T.reshape(boxes, n, n).transpose(0, 2, 1)  # column-major vec
        W_hi = hi[: n * n].T.reshape(boxes, n, n).transpose(0, 2, 1)
        t_lo, t_hi, regular = enclose_solutions(W_lo, W_hi, lo[n * n:].T, hi[n * n:].T)
        feasible = regular & np.all((t_lo >= self.t_min) & (t_hi <= self.t_max), axis=1)
        infeasible = regular & np.any((t_hi < self.t_min) | (t_lo > self.t_max), axis=1)
        return codes(feasible, infeasible)


class KrawczykMethod:
    """Static feasibility by Krawczyk's method: m = n > :data:`CRAMER_UP_TO`, no wrench."""

    key = "krawczyk"
    description = "Krawczyk's method on [W] T = [grad V] from W's enclosed entries"

    def covers(self, robot: Robot, wrench: bool) -> bool:
        return robot.m == robot.n > CRAMER_UP_TO and not wrench

    def verdicts(self, model: SymbolicModel, orientation: np.ndarray | None, compiled: bool,
                 wrench: np.ndarray | None) -> BoxVerdicts:
        return KrawczykVerdicts(model, orientation, compiled)
