"""The wrench-feasible workspace and wrench closure by brute force: one LP per pose over every
vertex of the external wrench box, in Cartesian statics (forces and moments about the body
origin, from the cables' unit vectors and attachment points in numpy), solved by cvxpy +
Clarabel. Nothing here uses W = -(dl/dq)^T, the generalized coordinates or facets.
"""

from __future__ import annotations

import itertools

import cvxpy as cp
import numpy as np
import rigid_reference


def cable_wrench_matrix(robot, q: np.ndarray) -> np.ndarray:
    """Column i: the wrench (force; moment about the body origin) of 1 N in cable i."""
    q = np.asarray(q, dtype=float)
    d = robot.dimension
    if robot.kind == "point":
        diff = robot.anchors - q
        return (diff / np.linalg.norm(diff, axis=1)[:, None]).T
    geometry = rigid_reference.geometry_of(robot)
    R = rigid_reference.rotation(geometry, q)
    arms = robot.attachments @ R.T  # R b_i, world
    units = robot.anchors - (q[:d] + arms)
    units /= np.linalg.norm(units, axis=1)[:, None]
    return np.vstack([units.T, _moment(arms, units).T])


def _moment(arm: np.ndarray, force: np.ndarray) -> np.ndarray:
    """arm x force along the last axis; the scalar (as one column) in 2-D."""
    if arm.shape[-1] == 2:
        return (arm[..., 0] * force[..., 1] - arm[..., 1] * force[..., 0])[..., None]
    return np.cross(arm, force)


def required_wrenches(robot, q: np.ndarray, half_widths: np.ndarray) -> np.ndarray:
    """Rows: the wrench the cables must supply at every vertex of the box, i.e. minus the
    weight and the external force (both at the centre of mass) and moment."""
    q = np.asarray(q, dtype=float)
    d = robot.dimension
    com = np.zeros(d)
    if robot.kind != "point":
        geometry = rigid_reference.geometry_of(robot)
        com = rigid_reference.rotation(geometry, q) @ robot.center_of_mass
    weight = np.zeros(d)
    weight[-1] = -robot.mass * robot.gravity
    rows = []
    for signs in itertools.product((-1.0, 1.0), repeat=len(half_widths)):
        external = np.asarray(signs) * half_widths
        force = weight + external[:d]
        moment = _moment(com, force) + external[d:] if robot.kind != "point" else []
        rows.append(-np.concatenate([force, moment]))
    return np.array(rows)


def tension_slack(robot, q: np.ndarray, half_widths: np.ndarray) -> float:
    """The largest s (N) with tensions in [T_min + s, T_max - s] for every required wrench;
    s >= 0 on the wrench-feasible workspace. -inf where no tension makes every wrench."""
    A = cable_wrench_matrix(robot, q)
    wrenches = required_wrenches(robot, q, half_widths)
    tensions = cp.Variable((robot.m, len(wrenches)))
    slack = cp.Variable()
    constraints = [A @ tensions == wrenches.T, tensions >= robot.t_min + slack,
                   tensions <= robot.t_max - slack]
    problem = cp.Problem(cp.Maximize(slack), constraints)
    problem.solve(solver=cp.CLARABEL)
    if problem.status in (cp.INFEASIBLE, cp.INFEASIBLE_INACCURATE):
        return -np.inf
    assert problem.status == cp.OPTIMAL, problem.status
    return float(slack.value)


def closure_share(robot, q: np.ndarray) -> float:
    """The largest s with A tau = 0, tau >= s, sum tau = 1 (0 where A lacks full row rank, -1
    where only tau = 0 balances): positive exactly where the cables' wrenches positively
    span the wrench space."""
    A = cable_wrench_matrix(robot, q)
    rank = np.linalg.matrix_rank(A, tol=1e-9)
    if rank < A.shape[0]:
        return 0.0
    if rank == A.shape[1]:  # no null space: only tau = 0 balances
        return -1.0
    tensions, share = cp.Variable(robot.m), cp.Variable()
    problem = cp.Problem(cp.Maximize(share),
                         [A @ tensions == 0, tensions >= share, cp.sum(tensions) == 1])
    problem.solve(solver=cp.CLARABEL)
    if problem.status in (cp.INFEASIBLE, cp.INFEASIBLE_INACCURATE):
        return -1.0
    assert problem.status == cp.OPTIMAL, problem.status
    return float(share.value)
