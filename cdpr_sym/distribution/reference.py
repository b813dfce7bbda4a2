"""Tension distribution stated as convex programs in cvxpy and solved by Clarabel: the
reference the generated fast paths are checked against.

The variables are the m tensions themselves (no null-space parameterisation), so these are
a second formulation of the same problems, not a second implementation of the fast path.
"""

from __future__ import annotations

import dataclasses
import time

import cvxpy as cp
import numpy as np

from cdpr_sym.distribution.methods import check_bounds
from cdpr_sym.errors import InvalidCase
from cdpr_sym.robot.tension_box import TensionBox

#: Clarabel's tolerances: tight, so the reference is good to well below 1e-6 N.
SOLVER_OPTIONS = {"tol_gap_abs": 1e-10, "tol_gap_rel": 1e-10, "tol_feas": 1e-10}
#: Statuses a solve may report; "infeasible": no tension in the box produces the wrench.
OPTIMAL, INFEASIBLE = "optimal", "infeasible"


@dataclasses.dataclass(frozen=True)
class ReferenceTension:
    """A reference solve: the tension (N; None when infeasible), the status and the
    solver's wall time (s)."""

    tau: np.ndarray | None
    status: str
    seconds: float


def min_norm_reference(W: np.ndarray, w: np.ndarray, t_min: float, t_max: float
                       ) -> ReferenceTension:
    """min |tau|_2 subject to W tau = w, t_min <= tau <= t_max (a QP)."""
    W, w = _checked(W, w, t_min, t_max)
    tau = cp.Variable(W.shape[1])
    return _solve(cp.Minimize(cp.sum_squares(tau)), tau, W, w, t_min, t_max)


def linf_reference(W: np.ndarray, w: np.ndarray, t_min: float, t_max: float
                   ) -> ReferenceTension:
    """min max_i |tau_i - (t_min + t_max) / 2| subject to W tau = w and the box (an LP): the
    tension that keeps the largest distance to the box's middle smallest."""
    W, w = _checked(W, w, t_min, t_max)
    tau = cp.Variable(W.shape[1])
    middle = TensionBox(t_min, t_max).middle
    return _solve(cp.Minimize(cp.norm(tau - middle, "inf")), tau, W, w, t_min, t_max)


def _checked(W: object, w: object, t_min: float, t_max: float) -> tuple[np.ndarray, np.ndarray]:
    """W (n x m, m >= n) and w (n) as finite float arrays, and the box checked; else
    :class:`InvalidCase` naming the argument."""
    check_bounds(t_min, t_max)
    arrays = []
    for field, value, ndim in (("W", W, 2), ("wrench", w, 1)):
        try:
            array = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise InvalidCase(field, f"expected a {ndim}-D array of numbers, got {value!r}"
                              ) from None
        if array.ndim != ndim or not array.size or not np.isfinite(array).all():
            raise InvalidCase(field, f"expected a finite {ndim}-D array of numbers, got "
                              f"shape {array.shape}")
        arrays.append(array)
    W, w = arrays
    if W.shape[1] < W.shape[0]:
        raise InvalidCase("W", f"expected at least as many columns (cables) as rows, got "
                          f"shape {W.shape}")
    if w.shape != (W.shape[0],):
        raise InvalidCase("wrench", f"expected {W.shape[0]} values for W of shape {W.shape}, "
                          f"got shape {w.shape}")
    return W, w


def _solve(objective, tau, W: np.ndarray, w: np.ndarray, t_min: float, t_max: float
           ) -> ReferenceTension:
    problem = cp.Problem(objective, [W @ tau == w, tau >= t_min, tau <= t_max])
    start = time.perf_counter()
    problem.solve(solver=cp.CLARABEL, **SOLVER_OPTIONS)
    seconds = time.perf_counter() - start
    if problem.status in (cp.INFEASIBLE, cp.INFEASIBLE_INACCURATE):
        return ReferenceTension(None, INFEASIBLE, seconds)
    if problem.status != cp.OPTIMAL:
        return ReferenceTension(None, str(problem.status), seconds)
    return ReferenceTension(np.asarray(tau.value, dtype=float), OPTIMAL, seconds)
