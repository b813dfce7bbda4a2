"""The paper's Assumption 1 as a certified property, and its proof over boxes.

Theorem 1 of the paper keeps the l2 design's command in [T_min, T_max] where
beta = (T_max - T_min) / 2 - |tau_1 - (T_min + T_max) / 2|_2 > 0 with tau_1 = W^-1 grad V
(and dq != 0). Multiplied by D^2 = (det W)^2 > 0 it is a polynomial in W's entries,
free of the division: h^2 D^2 - sum_i (N_i - c D)^2 > 0 with N_i Cramer's numerators
(:mod:`cdpr_sym.certify.cramer`). A box where D keeps one sign and the enclosure's lower
bound is > 0 holds it everywhere; a box where the upper bound is <= 0 holds it nowhere.
m = n <= :data:`~cdpr_sym.certify.cramer.CRAMER_UP_TO`, no wrench box.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from cdpr_sym.certify.cramer import CRAMER_UP_TO
from cdpr_sym.certify.enclosure import enclosure
from cdpr_sym.certify.poses import pose_inputs
from cdpr_sym.certify.static import unique_tensions
from cdpr_sym.certify.verdict import BoxVerdicts, codes
from cdpr_sym.model import SymbolicModel
from cdpr_sym.robot import Robot


def assumption_function(model: SymbolicModel, orientation: np.ndarray) -> ca.Function:
    """positions (d) -> [D, h^2 D^2 - sum_i (N_i - c D)^2]: the paper's Assumption 1,
    beta = h - |tau_1 - c|_2 > 0 with tau_1 = W^-1 grad V = N / D, c = (T_min + T_max) / 2
    and h = (T_max - T_min) / 2, multiplied by D^2 > 0 (no division): it holds at a pose
    exactly when the second entry is > 0. Where it holds (and dq != 0) Theorem 1's alpha
    and J_d keep the command in [T_min, T_max]."""
    robot = model.robot
    position, q = pose_inputs(robot, orientation)
    W = model.structure_matrix(q)
    gravity = model.grad_potential(q)
    determinant = ca.det(W)
    middle, half = robot.box.middle, robot.box.half
    spread = 0
    for i in range(model.n):
        replaced = ca.horzcat(*(gravity if j == i else W[:, j] for j in range(model.n)))
        spread = spread + (ca.det(replaced) - middle * determinant) ** 2
    return ca.Function("assumption", [position],
                       [ca.vertcat(determinant, half**2 * determinant**2 - spread)])


class AssumptionVerdicts:
    """Verdicts of the paper's Assumption 1 (:func:`assumption_function`): held on the whole
    box (D of one sign, the margin's lower bound > 0) or nowhere in it (upper bound <= 0)."""

    def __init__(self, model: SymbolicModel, orientation: np.ndarray, compiled: bool) -> None:
        self.margin = enclosure(assumption_function(model, orientation), compiled)

    def __call__(self, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
        lo, hi = self.margin((lower.T, upper.T))[0]
        regular = (lo[0] > 0) | (hi[0] < 0)
        return codes(regular & (lo[1] > 0), hi[1] <= 0)


class AssumptionMethod:
    """Assumption 1's margin by the mean-value form: m = n <= :data:`CRAMER_UP_TO`, no
    wrench box."""

    key = "assumption-1"
    description = "beta D^2 enclosed by the mean-value form"

    def covers(self, robot: Robot, wrench: bool) -> bool:
        return robot.m == robot.n <= CRAMER_UP_TO and not wrench

    def verdicts(self, model: SymbolicModel, orientation: np.ndarray | None, compiled: bool,
                 wrench: np.ndarray | None) -> BoxVerdicts:
        return AssumptionVerdicts(model, orientation, compiled)


class AssumptionOne:
    """The region where the paper's Assumption 1 holds (its Theorem 1 keeps the box there)."""

    key = "assumption-1"
    help = ("the region where the paper's Assumption 1 holds (its Theorem 1 keeps the box "
            "there; m = n <= 3)")
    methods = ("assumption-1",)
    title = "the region of Assumption 1"
    legend = ("holds", "does not hold")
    outcome = ("proven to hold Assumption 1", "proven not to")

    def statement(self, robot: Robot, wrench: bool) -> str:
        return ("the paper's Assumption 1: beta = (T_max - T_min) / 2 - |tau_1 - (T_min + "
                "T_max) / 2|_2 > 0 with tau_1 = W^-1 grad V; where it holds and dq != 0, "
                "Theorem 1 keeps the l2 design's command in the tension box")

    def refusal(self, robot: Robot, wrench: bool) -> str:
        return (f"Assumption 1 is certified for m = n <= {CRAMER_UP_TO} without a wrench box; "
                f"{robot.name} has m = {robot.m}, n = {robot.n}")

    def holds(self, robot: Robot, poses: np.ndarray, half_widths: np.ndarray) -> np.ndarray:
        """Whether beta > 0 at each pose (rows), from W and grad V in numpy."""
        tension, _ = unique_tensions(robot, poses, half_widths)
        middle, half = robot.box.middle, robot.box.half
        return half - np.linalg.norm(tension - middle, axis=1) > 0
