"""The ``box`` and ``linf`` designs stated as cvxpy problems and solved with Clarabel.

This is the modelling route and the reference for the generated fast path of
:mod:`cdpr_sym.control.exact_box`. Each stage is a parameterised (DPP) problem built once per
robot and re-solved with new parameter values each step:

1. ``alpha``:   maximise alpha in [0, 1] s.t. T_min <= tau_1 + alpha tau_2 + A j <= T_max;
2. ``linf``:    t* = min ||tau_pd + A j - mid||_inf   (``linf`` only, at the chosen alpha);
3. ``project``: min ||A j||_2^2 s.t. lower <= tau_pd + A j <= upper (the box, or for
   ``linf`` the box met with the l∞ ball of radius t* + slack), tau_pd = tau_1 + alpha tau_2.

A here is W^{-1} P(dq / ||dq||) (A for a unit-speed dq; j is rescaled by 1/||dq||), and is
set to zero below the low-speed threshold, as in the fast path. j is bounded by
``j_bound`` (N, never active in practice) so that the LP of stage 1 stays bounded along the
null direction of A; the reported j is the minimum-norm representative pinv(A) (A j).
"""

from __future__ import annotations

import dataclasses
import functools
import time

import casadi as ca
import cvxpy as cp
import numpy as np

from cdpr_sym.control.exact_box import _ExactBoxDesign
from cdpr_sym.control.flags import FLAG_INFEASIBLE
from cdpr_sym.control.interface import ControlOutput
from cdpr_sym.model import SymbolicModel

SOLVER_OPTIONS = {"tol_gap_abs": 1e-12, "tol_gap_rel": 1e-12, "tol_feas": 1e-12,
                  "tol_ktratio": 1e-10, "max_iter": 400, "warm_start": False}


@dataclasses.dataclass(frozen=True)
class CvxSolve:
    """One reference solve: the command, each stage's status and the solve time (s)."""

    output: ControlOutput
    statuses: tuple[str, ...]
    seconds: float


class CvxExactBoxDesign:
    """cvxpy + Clarabel statement of a ``box`` or ``linf`` design for one robot.

    Parameters
    ----------
    model : SymbolicModel
    design : BoxDesign or LinfDesign
        Supplies low_speed, alpha_margin and linf_slack.
    """

    def __init__(self, model: SymbolicModel, design: _ExactBoxDesign) -> None:
        self.model, self.design = model, design
        robot = model.robot
        n, n_j = robot.n, robot.n_j
        self.mid = robot.box.middle
        self.j_bound = 100.0 * robot.box.width
        self.tau_1, self.tau_2 = cp.Parameter(n, name="tau_1"), cp.Parameter(n, name="tau_2")
        self.tau_pd = cp.Parameter(n, name="tau_pd")
        self.A = cp.Parameter((n, n_j), name="A")
        self.lower, self.upper = cp.Parameter(n, name="lower"), cp.Parameter(n, name="upper")
        alpha, j = cp.Variable(name="alpha"), cp.Variable(n_j, name="j")
        tau = self.tau_1 + alpha * self.tau_2 + self.A @ j
        self.alpha_problem = cp.Problem(cp.Maximize(alpha), [
            tau >= robot.t_min, tau <= robot.t_max, alpha >= 0, alpha <= 1,
            cp.norm(j, "inf") <= self.j_bound])
        self._alpha = alpha
        t, j2 = cp.Variable(name="t"), cp.Variable(n_j, name="j")
        self.linf_problem = cp.Problem(cp.Minimize(t), [
            cp.abs(self.tau_pd + self.A @ j2 - self.mid) <= t,
            cp.norm(j2, "inf") <= self.j_bound])
        j3 = cp.Variable(n_j, name="j")
        self._j_project = j3
        self.project_problem = cp.Problem(cp.Minimize(cp.sum_squares(self.A @ j3)), [
            self.tau_pd + self.A @ j3 >= self.lower, self.tau_pd + self.A @ j3 <= self.upper])
        q, dq, goal = ca.SX.sym("q", n), ca.SX.sym("dq", n), ca.SX.sym("goal", n)
        k, r_d = ca.SX.sym("k", n), ca.SX.sym("r_d", n)
        W = model.structure_matrix(q)
        speed = ca.norm_2(dq)
        A_unit = ca.solve(W, model.p_matrix(dq / ca.fmax(speed, design.low_speed)))
        self._pieces = ca.Function(
            "pieces", [q, dq, goal, k, r_d],
            [model.static_tension(q), -ca.solve(W, k * (q - goal) + r_d * dq),
             A_unit, speed])

    @property
    def problems(self) -> tuple[cp.Problem, ...]:
        """The parameterised problems (each DPP)."""
        return (self.alpha_problem, self.linf_problem, self.project_problem)

    def solve(self, q: np.ndarray, dq: np.ndarray, q_goal: np.ndarray, k: np.ndarray,
              r_d: np.ndarray) -> CvxSolve:
        """Solve the design at one state with Clarabel."""
        start = time.perf_counter()
        robot = self.model.robot
        tau_1, tau_2, A_unit, speed = (np.array(x) for x in self._pieces(q, dq, q_goal, k, r_d))
        tau_1, tau_2, speed = tau_1.ravel(), tau_2.ravel(), float(speed.item())
        slow = speed < self.design.low_speed
        A = np.zeros_like(A_unit) if slow else A_unit
        self.tau_1.value, self.tau_2.value, self.A.value = tau_1, tau_2, A
        self.alpha_problem.solve(solver=cp.CLARABEL, **SOLVER_OPTIONS)
        statuses = [self.alpha_problem.status]
        alpha_max = self._alpha.value
        if self.alpha_problem.status not in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE) or \
                alpha_max is None or alpha_max <= 0:
            tau = np.clip(tau_1 + tau_2, robot.t_min, robot.t_max)
            output = ControlOutput(tau, 1.0, np.nan, np.zeros(robot.n_j), FLAG_INFEASIBLE)
            return CvxSolve(output, tuple(statuses), time.perf_counter() - start)
        alpha_max = min(float(alpha_max), 1.0)
        # as the fast path: alpha = 1 only when alpha = 1 itself is feasible (to solver accuracy)
        alpha = alpha_max * (1 - self.design.alpha_margin) if alpha_max < 1 - 1e-11 else 1.0
        tau_pd = tau_1 + alpha * tau_2
        lower = np.full(robot.n, robot.t_min)
        upper = np.full(robot.n, robot.t_max)
        self.tau_pd.value = tau_pd
        if self.design.linf_slack is not None:
            self.linf_problem.solve(solver=cp.CLARABEL, **SOLVER_OPTIONS)
            statuses.append(self.linf_problem.status)
            radius = float(self.linf_problem.value) + self.design.linf_slack
            lower, upper = np.maximum(lower, self.mid - radius), np.minimum(upper,
                                                                            self.mid + radius)
        self.lower.value, self.upper.value = lower, upper
        self.project_problem.solve(solver=cp.CLARABEL, **SOLVER_OPTIONS)
        statuses.append(self.project_problem.status)
        if self._j_project.value is None:  # solver failure: recorded, handled as infeasible
            tau = np.clip(tau_1 + tau_2, robot.t_min, robot.t_max)
            output = ControlOutput(tau, 1.0, np.nan, np.zeros(robot.n_j), FLAG_INFEASIBLE)
            return CvxSolve(output, tuple(statuses), time.perf_counter() - start)
        tau_3 = A @ self._j_project.value
        j = np.linalg.pinv(A) @ tau_3 / max(speed, self.design.low_speed) if not slow \
            else np.zeros(robot.n_j)
        output = ControlOutput(tau_pd + tau_3, alpha, np.nan, j, 0)
        return CvxSolve(output, tuple(statuses), time.perf_counter() - start)


@functools.lru_cache(maxsize=16)
def cvx_design(model: SymbolicModel, design: _ExactBoxDesign) -> CvxExactBoxDesign:
    """A cached :class:`CvxExactBoxDesign` (building the problems costs ~0.1 s)."""
    return CvxExactBoxDesign(model, design)
