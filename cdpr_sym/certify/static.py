"""Static (and wrench) feasibility as a certified property: the workspace where the platform
can be held at rest with every tension in [T_min, T_max].

With m = n the tension holding a pose is unique, T = W^-1 grad V (against a wrench box of
half-widths h: T(0) -+ |W^-1 J^T| h); with m > n some T in the box must solve W T = grad V
(- J^T w for every wrench w of the box). Which proof decides a box depends on the robot
(:mod:`cdpr_sym.certify.cramer`, :mod:`~cdpr_sym.certify.krawczyk`,
:mod:`~cdpr_sym.certify.facets`, :mod:`~cdpr_sym.certify.anchored`); the pointwise test
(:meth:`StaticFeasibility.holds`) is the sampled check's independent reference.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from cdpr_sym.model import SymbolicModel
from cdpr_sym.robot import Robot

#: Poses per numpy pass of the pointwise tests.
_CHUNK = 100_000


class StaticFeasibility:
    """Static feasibility, or wrench feasibility against the robot's wrench box."""

    key = "static"
    help = "static (or wrench) feasibility"
    methods = ("cramer", "cramer-wrench", "krawczyk", "facets", "anchored")
    title = "certified static workspace"
    legend = ("feasible", "infeasible")
    outcome = ("proven feasible", "proven infeasible")

    def statement(self, robot: Robot, wrench: bool) -> str:
        if robot.m > robot.n:
            return ("static feasibility: some tension T in [T_min, T_max] on every cable with "
                    "W T = grad V" if not wrench else "wrench feasibility: for every "
                    "external wrench w of the box some tension T in [T_min, T_max] on every "
                    "cable with W T = grad V - J^T w")
        return ("static feasibility: the unique tension W^-1 grad V in [T_min, T_max] on "
                "every cable" if not wrench else "wrench feasibility: the tension W^-1 "
                "(grad V - J^T w) in [T_min, T_max] on every cable for every external "
                "wrench w of the box")

    def refusal(self, robot: Robot, wrench: bool) -> str:
        if robot.underactuated:
            return (f"{robot.name} has fewer cables than degrees of freedom (m = {robot.m} < "
                    f"n = {robot.n}): it rests only on its equilibrium manifold, which has no "
                    "volume in the frame to prove; its positions at rest are proven by "
                    "cdpr_sym.certify.equilibria (a planar body on two cables)")
        return f"no proof method covers {robot.name} (m = {robot.m}, n = {robot.n})"

    def holds(self, robot: Robot, poses: np.ndarray, half_widths: np.ndarray) -> np.ndarray:
        """Whether each pose (rows) is statically (wrench) feasible: with m > n by the
        sampled workspace's hyperplane shifting in generated C
        (:class:`~cdpr_sym.workspace.wrench.WrenchEvaluator`, which sees the pose, not a
        box), else from the unique tension in numpy."""
        if robot.m > robot.n:
            from cdpr_sym.workspace.wrench import WrenchEvaluator

            box = half_widths if half_widths.size else np.zeros(robot.wrench_half_widths.size)
            evaluator = WrenchEvaluator(robot)
            return np.concatenate([evaluator.classify(poses[start:start + _CHUNK], box).feasible
                                   for start in range(0, len(poses), _CHUNK)])
        tension, spread = unique_tensions(robot, poses, half_widths)
        return np.all((tension - spread >= robot.t_min) & (tension + spread <= robot.t_max),
                      axis=1)


def unique_tensions(robot: Robot, poses: np.ndarray, half_widths: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray | float]:
    """m = n: the tension holding each pose at rest, W^-1 grad V (poses, m; N), and its
    spread over the wrench box, |W^-1 J^T| h (poses, m; 0.0 without a box), by numpy's
    solve at W and grad V evaluated by CasADi."""
    model = SymbolicModel(robot)
    q = ca.SX.sym("q", robot.n)
    terms = ca.Function("terms", [q], [model.structure_matrix(q), model.grad_potential(q),
                                       ca.densify(model.wrench_jacobian(q).T)])
    tensions, spreads = [], []
    for start in range(0, len(poses), _CHUNK):
        chunk = poses[start:start + _CHUNK]
        W, gravity, transposed = terms.map(len(chunk))(chunk.T)
        W = np.array(W).T.reshape(len(chunk), robot.n, robot.m).transpose(0, 2, 1)
        tensions.append(np.linalg.solve(W, np.array(gravity).T[..., None])[..., 0])
        if half_widths.size:
            J_T = np.array(transposed).T.reshape(len(chunk), -1, robot.n).transpose(0, 2, 1)
            spreads.append(np.abs(np.linalg.solve(W, J_T)) @ half_widths)
    tension = np.concatenate(tensions) if tensions else np.zeros((0, robot.m))
    return tension, (np.concatenate(spreads) if spreads else 0.0)
